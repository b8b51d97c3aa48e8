# Stub of brdfkit.hypernet's lazily loaded names (brdfkit/hypernet/__init__.py);
# tests/test_stubs.py checks that it names what the package serves.
from brdfkit.hypernet.encoding import encode_samples as encode_samples
from brdfkit.hypernet.encoding import encode_table as encode_table
from brdfkit.hypernet.loaded import ModelCache as ModelCache
from brdfkit.hypernet.loaded import LoadedNetwork as LoadedNetwork
from brdfkit.hypernet.loaded import NeuralModel as NeuralModel
from brdfkit.hypernet.network_file import MODEL_FORMAT as MODEL_FORMAT
from brdfkit.hypernet.network_file import MODEL_VERSION as MODEL_VERSION
from brdfkit.hypernet.network_file import MODEL_VERSIONS as MODEL_VERSIONS
from brdfkit.hypernet.network_file import load_network as load_network
from brdfkit.hypernet.network_file import save_network as save_network
from brdfkit.hypernet.network_file import state_digest as state_digest
from brdfkit.hypernet.network_file import weights_digest as weights_digest
from brdfkit.hypernet.network import IN_FEATURES as IN_FEATURES
from brdfkit.hypernet.network import OUT_FEATURES as OUT_FEATURES
from brdfkit.hypernet.network import HyperBRDF as HyperBRDF
from brdfkit.hypernet.network import HyperConfig as HyperConfig
from brdfkit.hypernet.network import hyper_loss as hyper_loss
from brdfkit.hypernet.network import hyponet_forward as hyponet_forward
from brdfkit.hypernet.network import hyponet_shapes as hyponet_shapes
from brdfkit.hypernet.neural_brdf import NeuralBRDF as NeuralBRDF
from brdfkit.hypernet.packing import load_builtin as load_builtin
from brdfkit.hypernet.packing import manifest_entry as manifest_entry
from brdfkit.hypernet.packing import pack_network as pack_network

__all__: list[str]
