"""Bad safetensors files (models, reference tables, PCA bases) through the commands and
readers that take them (issue 6, docs/errors.md).

Each case: exit code 2, exactly one line on stderr that names the file and the problem,
no traceback, no output file and no temporary file left behind (the library-level checks
live in ``test_modelfile.py``). The bad models: the ``bad_models`` fixture of
``conftest.py`` (``helpers_bad_input.bad_model_files``).
"""

from __future__ import annotations

import os
import time

import pytest

from brdfkit.errors import FormatError

from conftest import one_error_line, run_cli
from helpers_bad_input import check_line, rewrite_header
from helpers_model import material_table


@pytest.mark.slow
def test_model_whose_header_length_starts_with_0x80_loads(tmp_path):
    # Regression: a safetensors header length with low byte 0x80 (one file in 32) was
    # refused as a pickle; brdfkit.hypernet.training.loop had to pad its metadata to avoid it.
    import torch

    from brdfkit.hypernet.network import HyperBRDF, HyperConfig
    from brdfkit.hypernet.network_file import load_network, save_network

    torch.manual_seed(0)
    net = HyperBRDF(HyperConfig(latent_dim=3, encoder_hidden=(4,), hypo_hidden=4, hypo_layers=1,
                                decoder_hidden=4, decoder_layers=1))
    path = tmp_path / "m.safetensors"
    for pad in range(64):
        fp = save_network(path, net, material_table(0), {"pad": "_" * (8 * pad)})
        if path.read_bytes()[:1] == b"\x80":
            break
    else:
        pytest.fail("no padding gave a header length with low byte 0x80")
    assert load_network(path, "cpu").digest == fp


MODEL_COMMANDS = {  # command -> arguments before -m, given the good folder and the output folder
    "render": lambda g, o: ["render", g / "a.emb", "-o", o / "x.exr", "--resolution", "8", "--quiet"],
    "metrics": lambda g, o: ["metrics", g / "a.emb", g / "mat.binary", "--json", "--resolution", "16"],
    "encode": lambda g, o: ["encode", g / "mat.binary", "-o", o],
    "decode": lambda g, o: ["decode", g / "a.emb", "-o", o / "x.binary"],
    "sparse": lambda g, o: ["sparse", g / "samples.csv", "-o", o / "x.binary", "--emb", o / "x.emb"],
    "interpolate": lambda g, o: ["interpolate", g / "a.emb", g / "b.emb", "--t", "0.5", "-o", o / "x.emb",
                                 "--binary", o / "x.binary"],
    "view": lambda g, o: ["view", g / "a.emb", "-o", o / "p.html"],
}
BAD_MODEL_NAMES = ["missing", "directory", "empty", "text", "pickle", "torch_save", "truncated_header",
                   "truncated_payload", "reference_table", "merl_table"]


@pytest.mark.parametrize("command", sorted(MODEL_COMMANDS))
@pytest.mark.parametrize("name", BAD_MODEL_NAMES)
def test_bad_model_through_every_command(good, bad_models, tmp_path, capsys, command, name):
    path, message = bad_models[name]
    code, _, err = run_cli(capsys, [*MODEL_COMMANDS[command](good, tmp_path), "-m", path])
    assert code == 2
    check_line(one_error_line(err), path, message)
    assert os.listdir(tmp_path) == []  # no output, no temporary file


@pytest.mark.parametrize("name, message", [
    ("model", "a hypernetwork file, not the PCA basis --method ipca takes"),
    ("empty", "not a valid safetensors file (Error while deserializing header: header too small)"),
    ("pickle", "not a valid safetensors file (Error while deserializing header: "),
    ("truncated_header", "not a valid safetensors file (Error while deserializing header: "),
    ("merl_table", "not a valid safetensors file (Error while deserializing header: "),
])
def test_bad_basis_through_sparse_ipca(good, bad_models, tmp_path, capsys, name, message):
    # The PCA baseline takes its basis with -m. Regression: load_basis wrapped its own
    # "not a brdfkit PCA basis" error again ("not a valid safetensors file (x: not a ...)").
    path = good / "model.safetensors" if name == "model" else bad_models[name][0]
    code, _, err = run_cli(capsys, ["sparse", good / "samples.csv", "--method", "ipca", "-m", path,
                              "-o", tmp_path / "x.binary"])
    assert code == 2
    line = one_error_line(err)
    assert line.startswith(f"brdfkit: error: {path}: {message}") and line.count(str(path)) == 1, line
    assert os.listdir(tmp_path) == []


# --- crafted headers (found by benchmarks/fuzz_parsers.py and by hand) ---------------------

@pytest.mark.parametrize("change, message", [
    ({"latent_dim": 10**7}, "latent_dim = 10000000 does not fit the 30 tensors"),
    ({"decoder_hidden": 20000, "decoder_layers": 30}, "decoder_layers = 30 does not fit|decoder_hidden = 20000"),
    ({"hypo_layers": 10**6}, "hypo_layers = 1000000 does not fit"),
    ({"latent_dim": 1.5}, "latent_dim = 1.5 is not a whole number"),
])
def test_model_config_asking_for_a_huge_network_is_refused_at_once(good, tmp_path, change, message):
    # Regression: the network was built from the config before its shapes were compared
    # with the file's tensors: latent_dim = 10^7 took 37 s and 4.7 GB, decoder_hidden =
    # 20000 x 30 layers was killed for memory.
    import json
    import re

    from brdfkit.hypernet.network_file import load_network

    def edit(header):
        cfg = json.loads(header["__metadata__"]["config"])
        cfg.update(change)
        header["__metadata__"]["config"] = json.dumps(cfg)

    path = tmp_path / "crafted.safetensors"
    path.write_bytes(rewrite_header((good / "model.safetensors").read_bytes(), edit))
    t0 = time.perf_counter()
    with pytest.raises(FormatError, match="model config cannot be built") as e:
        load_network(path, "cpu")
    assert time.perf_counter() - t0 < 2.0
    assert re.search(message, str(e.value)), str(e.value)


def test_ipca_basis_with_materials_not_a_list(tmp_path):
    # Found by benchmarks/fuzz_parsers.py: metadata materials = "5" raised a TypeError.
    from brdfkit.testing.fuzzing import ipca_seed
    from brdfkit.basis import load_basis

    for bad in ("5", "null", '{"a": 1}', "[1, 2]"):
        path = tmp_path / "basis.safetensors"
        path.write_bytes(rewrite_header(ipca_seed(), lambda h: h["__metadata__"].update(materials=bad)))
        with pytest.raises(FormatError, match="'materials' is not a list of names"):
            load_basis(path)


@pytest.mark.slow
def test_messages_stay_one_line_whatever_the_file_holds(good, tmp_path):
    # Found by benchmarks/fuzz_parsers.py: a "fingerprint" (the digest key) "\n" in a network file's metadata,
    # and a safetensors header key with a line break (quoted by the parser's error), gave
    # two-line messages. BrdfkitError now prints every non-printable character as a space.
    from brdfkit.errors import FormatError
    from brdfkit.hypernet.mapping import load_reference, save_reference
    from brdfkit.hypernet.network_file import load_network

    from conftest import run_brdfkit

    bad_fp = tmp_path / "fp.safetensors"
    bad_fp.write_bytes(rewrite_header((good / "model.safetensors").read_bytes(),
                                       lambda h: h["__metadata__"].update(fingerprint="\n\x1b[31mred")))
    with pytest.raises(FormatError) as e:
        load_network(bad_fp, "cpu")
    assert str(e.value).isprintable() and "weights do not match the recorded digest" in str(e.value)
    save_reference(tmp_path / "ref.safetensors", material_table(0))
    bad_ref = tmp_path / "bad-ref.safetensors"
    bad_ref.write_bytes(rewrite_header((tmp_path / "ref.safetensors").read_bytes(),
                                        lambda h: h.update({"": [{"\n": None}]})))
    with pytest.raises(FormatError) as e:
        load_reference(bad_ref)
    assert str(e.value).isprintable() and "not a valid safetensors file" in str(e.value)
    r = run_brdfkit(["decode", good / "a.emb", "-m", bad_fp, "-o", tmp_path / "x.binary"])
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1 and "\x1b" not in r.stderr
