# Stub of brdfkit's lazily loaded public API (brdfkit/__init__.py), for IDEs and type
# checkers; tests/test_stubs.py checks that it names what the package serves.
from brdfkit import geometry as geometry
from brdfkit.acquisition.planning import plan_directions as plan_directions
from brdfkit.acquisition.sampling import draw_samples as draw_samples
from brdfkit.acquisition.sampling import measure_samples as measure_samples
from brdfkit.api import decode as decode
from brdfkit.api import encode as encode
from brdfkit.api import fit as fit
from brdfkit.api import interpolate as interpolate
from brdfkit.api import load_model as load_model
from brdfkit.api import sparse as sparse
from brdfkit.errors import BrdfkitError as BrdfkitError
from brdfkit.errors import FormatError as FormatError
from brdfkit.errors import InputError as InputError
from brdfkit.hypernet import mapping as mapping
from brdfkit.hypernet.mapping import from_mapped as from_mapped
from brdfkit.hypernet.mapping import median_reference as median_reference
from brdfkit.hypernet.mapping import to_mapped as to_mapped
from brdfkit.io import merl as merl
from brdfkit.io import samples as samples
from brdfkit.io.directions import DirectionSet as DirectionSet
from brdfkit.io.directions import read_directions as read_directions
from brdfkit.io.directions import write_directions as write_directions
from brdfkit.io.embedding import Embedding as Embedding
from brdfkit.io.embedding import read_embedding as read_embedding
from brdfkit.io.embedding import write_embedding as write_embedding
from brdfkit.io.merl import read_merl as read_merl
from brdfkit.io.merl import write_merl as write_merl
from brdfkit.io.samples import SampleSet as SampleSet
from brdfkit.io.samples import read_samples as read_samples
from brdfkit.io.samples import write_samples as write_samples
from brdfkit.materials import synthetic as synthetic
from brdfkit.runtime import set_torch_threads as set_torch_threads

__version__: str
__all__: list[str]

def lazy_attributes(package: str, names: dict[str, str]) -> tuple: ...
