"""``terratheme pack / unpack / info`` through ``app.cli.main``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import read_image, write_image
from terratheme.core.packing import PackedLayer, load_layer, write_layer_image
from terratheme.core.packing.index_png import display_colours, read_index_image


@pytest.fixture
def vector_png(tmp_path, shared_vectors):
    vec = json.loads((shared_vectors / "sfc_8x8.json").read_text())
    path = tmp_path / "fig2.png"
    write_image(path, np.array(vec["index_image"], np.uint8)[:, :, None])
    return path, vec


@pytest.mark.parametrize("fmt", ["compact", "seed"])
def test_pack_info_unpack(tmp_path, vector_png, capsys, fmt):
    png, vec = vector_png
    out = tmp_path / "fig2.ttp"
    assert main(["pack", str(png), str(out), "--format", fmt]) == 0
    assert "15 runs" in capsys.readouterr().out
    assert main(["info", str(out), "--json", "--runs"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["width"], info["height"], info["curve"]) == (8, 8, "hilbert")
    assert info["S"] == vec["hilbert_runs"]["S"] and info["P"] == vec["hilbert_runs"]["P"]
    assert info["run_count"] == 15 and info["file_bytes"] == out.stat().st_size
    assert info["palette"] == [[i] for i in range(7)]
    # Compact keeps the smaller payload: here the plane (version 2).
    assert (info["format"], info["version"]) == {"compact": ("plane", 2), "seed": ("seed", 1)}[fmt]
    back = tmp_path / "back.png"
    assert main(["unpack", str(out), str(back)]) == 0
    assert "palette PNG" in capsys.readouterr().out
    # A palette PNG: the stored values are the indices, shown in distinct colours.
    indices, colours = read_index_image(back)
    assert np.array_equal(indices, np.array(vec["index_image"], np.uint8))
    assert np.array_equal(colours, display_colours(7))
    assert np.array_equal(read_image(back), display_colours(7)[indices])


def test_palette_png_round_trip_keeps_indices_and_colours(tmp_path, vector_png, capsys):
    png, vec = vector_png
    first, again = tmp_path / "a.ttp", tmp_path / "b.ttp"
    main(["pack", str(png), str(first)])
    main(["unpack", str(first), str(tmp_path / "a.png")])
    # Packing the palette PNG keeps its indices as values and its colours for display.
    assert main(["pack", str(tmp_path / "a.png"), str(again)]) == 0
    layer = PackedLayer.load(again)
    assert layer.identity and np.array_equal(layer.colours, display_colours(7))
    assert np.array_equal(layer.unpack(), np.array(vec["index_image"], np.uint8))
    assert main(["info", str(again), "--json"]) == 0
    assert json.loads(capsys.readouterr().out.splitlines()[-1])["version"] == 2
    main(["unpack", str(again), str(tmp_path / "b.png")])
    assert (tmp_path / "b.png").read_bytes() == (tmp_path / "a.png").read_bytes()


def test_unpack_to_tiff_writes_the_values(tmp_path, vector_png):
    png, vec = vector_png
    out = tmp_path / "fig2.ttp"
    main(["pack", str(png), str(out)])
    assert main(["unpack", str(out), str(tmp_path / "back.tif")]) == 0
    assert np.array_equal(read_image(tmp_path / "back.tif")[:, :, 0], vec["index_image"])


@pytest.mark.parametrize("command", ["pack", "unpack"])
def test_output_that_is_the_input_is_refused(tmp_path, vector_png, capsys, command):
    png, _ = vector_png
    layer = tmp_path / "fig2.ttp"
    main(["pack", str(png), str(layer)])
    capsys.readouterr()
    target = png if command == "pack" else layer
    before = target.read_bytes()
    assert main([command, str(target), str(target)]) == 2
    err = capsys.readouterr().err
    assert "is also an input" in err and err.count("\n") == 1
    assert target.read_bytes() == before


def test_morton_and_auto(tmp_path, vector_png, capsys):
    png, vec = vector_png
    for curve, runs in (("morton", 22), ("auto", 15)):
        out = tmp_path / f"{curve}.ttp"
        assert main(["pack", str(png), str(out), "--curve", curve]) == 0
        capsys.readouterr()
        assert main(["info", str(out), "--json"]) == 0
        info = json.loads(capsys.readouterr().out)
        assert info["run_count"] == runs and "S" not in info


def test_info_text(tmp_path, vector_png, capsys):
    png, _ = vector_png
    out = tmp_path / "a.ttp"
    main(["pack", str(png), str(out)])
    capsys.readouterr()
    assert main(["info", str(out), "--runs"]) == 0
    text = capsys.readouterr().out
    assert "run_count: 15" in text and "curve: hilbert" in text


def test_rgb_palette_reduction(tmp_path, capsys):
    img = np.random.default_rng(1).integers(0, 256, (30, 40, 3)).astype(np.uint8)
    png = tmp_path / "photo.png"
    write_image(png, img)
    out = tmp_path / "photo.ttp"
    assert main(["pack", str(png), str(out)]) == 2
    err = capsys.readouterr().err
    assert "more than the 256" in err and "(--reduce-palette)" in err and err.count("\n") == 1
    assert not out.exists()
    assert main(["pack", str(png), str(out), "--reduce-palette"]) == 0
    assert "palette reduced from" in capsys.readouterr().out
    back = tmp_path / "back.png"
    assert main(["unpack", str(out), str(back)]) == 0
    assert read_image(back).shape == (30, 40, 3)


def test_errors_exit_2_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.ttp"
    bad.write_bytes(b"TTPK" + bytes(10))
    assert main(["unpack", str(bad), str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "truncated" in err and err.count("\n") == 1
    assert not (tmp_path / "x.png").exists()
    assert main(["info", str(tmp_path / "missing.ttp")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_info_reads_the_header_only(tmp_path, capsys):
    # A whole 65536 x 65536 layer: info answers from the header, S and P need --runs.
    layer = PackedLayer.from_runs(65536, 65536, "hilbert", [2**32 - 1], [3],
                                  np.arange(4, dtype=np.uint8), identity=True, squeeze=True)
    path = tmp_path / "big.ttp"
    layer.save(path, format="seed")
    assert main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["run_count"] == 1 and layer.memory_bytes <= info["memory_bytes_max"]
    data = bytearray(path.read_bytes())
    data[-1] ^= 1
    path.write_bytes(bytes(data))
    assert main(["info", str(path)]) == 2
    assert "checksum" in capsys.readouterr().err


def test_info_imports_no_numba(tmp_path, vector_png):
    import subprocess
    import sys

    png, _ = vector_png
    out = tmp_path / "fig2.ttp"
    main(["pack", str(png), str(out)])
    code = ("import sys; from terratheme.app.cli import main; main(['info', sys.argv[1]]); "
            "assert 'numba' not in sys.modules, 'numba loaded'")
    run = subprocess.run([sys.executable, "-c", code, str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "run_count: 15" in run.stdout


STREAMED_UNPACK = r"""
import resource, sys
import numpy as np
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.packing import PackedLayer, load_layer, write_layer_image

# Warm the kernels and writers on a small layer, then cap the address space.
small = PackedLayer.from_runs(64, 64, "hilbert", [4095], [1], np.arange(2, dtype=np.uint8),
                              identity=True, squeeze=True)
small.save(sys.argv[3] + "/small.ttp")
assert main(["unpack", sys.argv[3] + "/small.ttp", sys.argv[3] + "/small" + sys.argv[4]]) == 0
from terratheme.app.cli import MIN_ADDRESS_SPACE_MIB
vm = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmSize"))
# 256 MiB above the warm process, and not below the floor the CLI checks for unpack
cap = max(vm + (256 << 20), MIN_ADDRESS_SPACE_MIB["unpack"] << 20)
resource.setrlimit(resource.RLIMIT_AS, (cap,) * 2)
sys.exit(main(["unpack", sys.argv[1], sys.argv[2]]))
"""


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_unpack_of_a_46_byte_65536_square_layer_streams(tmp_path, suffix):
    import subprocess
    import sys

    layer = PackedLayer.from_runs(65536, 65536, "hilbert", [2**32 - 1], [3],
                                  np.arange(4, dtype=np.uint8), identity=True, squeeze=True)
    src = tmp_path / "big.ttp"
    layer.save(src, format="seed")
    assert src.stat().st_size == 46
    out = tmp_path / f"big{suffix}"
    run = subprocess.run([sys.executable, "-c", STREAMED_UNPACK, str(src), str(out),
                          str(tmp_path), suffix], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    # 4 Gi texels written within 256 MiB: read back a corner and the middle row.
    from terratheme.core.io.images import read_region

    assert (read_region(out, 65000, 0, 536, 3)[..., 0] == (3 if suffix == ".tif" else 242)).all()


def test_unpack_of_a_huge_layer_to_a_format_written_whole_is_refused(tmp_path, capsys):
    layer = PackedLayer.from_runs(65536, 65536, "hilbert", [2**32 - 1], [3],
                                  np.arange(4, dtype=np.uint8), identity=True, squeeze=True)
    layer.save(tmp_path / "big.ttp")
    assert main(["unpack", str(tmp_path / "big.ttp"), str(tmp_path / "big.bmp")]) == 2
    assert "band by band only as .png" in capsys.readouterr().err


@pytest.mark.parametrize("suffix", [".jpg", ".JPEG", ".webp", ".avif"])
def test_unpack_to_a_lossy_format_is_refused_before_any_work(tmp_path, vector_png, capsys,
                                                             suffix):
    png, _ = vector_png
    assert main(["pack", str(png), str(tmp_path / "v.ttpack")]) == 0
    capsys.readouterr()
    out = tmp_path / f"v{suffix}"
    assert main(["unpack", str(tmp_path / "v.ttpack"), str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "lossy" in err and str(out) in err
    assert not out.exists()
    with pytest.raises(TerrathemeError, match="lossy"):
        write_layer_image(load_layer(tmp_path / "v.ttpack"), out)
