"""``terratheme pack / unpack / info`` through ``app.cli.main``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from core.io.images import read_image, write_image


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
    back = tmp_path / "back.png"
    assert main(["unpack", str(out), str(back)]) == 0
    assert np.array_equal(read_image(back), read_image(png))


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
    assert "more than the 256" in err and err.count("\n") == 1
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
