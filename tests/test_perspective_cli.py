"""Issues 6, 16 and 18: ``terratheme perspective`` (app/commands/perspective.py)."""

from __future__ import annotations

import numpy as np
import pytest
import terratheme.app.commands.perspective as command
from terratheme.app.cli import main
from terratheme.core.io.images import read_image, write_image


def _random_texture(h, w, c=3, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (h, w, c), dtype=np.uint8)


@pytest.fixture
def src(tmp_path):
    path = tmp_path / "tex.png"
    write_image(path, _random_texture(16, 16))
    return path


def _run(*argv, cache=None):
    extra = ["--no-cache"] if cache is None else ["--cache-dir", str(cache)]
    return main(["perspective", *map(str, argv), *extra])


def _nearest(tmp_path, texture, size, mapping, *extra) -> np.ndarray:
    """What ``perspective --method nearest --size SIZE --mapping M`` renders of ``texture``."""
    src, out = tmp_path / "tex.png", tmp_path / "out.png"
    write_image(src, texture)
    assert _run(src, out, "--method", "nearest", "--size", size, "--mapping", mapping,
                *extra) == 0
    return read_image(out)


def test_identity_mapping_nearest_round_trips(tmp_path):
    tex = _random_texture(6, 9)
    np.testing.assert_array_equal(_nearest(tmp_path, tex, "9x6", "1,0,0,0,1,0,0,0,1"), tex)


def test_a_negative_first_value_is_a_value_not_an_option(tmp_path):
    # U = 9 - x: the texture mirrored left-right
    tex = _random_texture(6, 9)
    for mapping in ("-1,0,9,0,1,0,0,0,1", "-1e0,0,9,0,1,0,0,0,1"):
        np.testing.assert_array_equal(_nearest(tmp_path, tex, "9x6", mapping), tex[:, ::-1])


def test_a_negative_camera_height_is_a_clear_error(src, tmp_path, capsys):
    assert _run(src, tmp_path / "o.png", "--camera", "-60,10,0,60") == 2
    assert "height must be > 0" in capsys.readouterr().err


def test_max_texture_downscales_and_keeps_the_view_in_input_texels(tmp_path, capsys):
    # 2 x 2 blocks of one value: area-averaging to half size keeps every block
    small = _random_texture(4, 6)
    big = np.repeat(np.repeat(small, 2, axis=0), 2, axis=1)
    frame = _nearest(tmp_path, big, "6x4", "2,0,0,0,2,0,0,0,1", "--max-texture", "6")
    np.testing.assert_array_equal(frame, small)
    assert "used at 6 x 4" in capsys.readouterr().out


def test_a_frame_that_needs_less_detail_reads_a_reduced_texture(tmp_path, capsys):
    # 4 texels per pixel everywhere: the texture at a quarter is enough
    small = _random_texture(4, 4)
    big = np.repeat(np.repeat(small, 4, axis=0), 4, axis=1)
    np.testing.assert_array_equal(_nearest(tmp_path, big, "4x4", "4,0,0,0,4,0,0,0,1"), small)
    assert "used at 4 x 4" in capsys.readouterr().out


@pytest.mark.parametrize("method", ["parallelogram", "ewa", "reference"])
def test_camera_renders(src, tmp_path, method):
    out = tmp_path / f"{method}.png"
    assert _run(src, out, "--method", method, "--size", "20x10",
                "--camera", "4,12,30,60,3,3") == 0
    img = read_image(out)
    assert img.shape == (10, 20, 3) and img.dtype == np.uint8


def test_default_view_needs_no_camera(src, tmp_path, capsys):
    out = tmp_path / "sub" / "default.png"
    assert _run(src, out, "--size", "32x18") == 0
    img = read_image(out).astype(float)
    # sky on top, ground below
    np.testing.assert_allclose(img[0, 0], np.array([0.62, 0.74, 0.88]) * 255, atol=1)
    assert img[-1].std() > 5
    assert "32 x 18 pixels, parallelogram" in capsys.readouterr().out


def test_help_has_examples(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["perspective", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert "examples:" in text and "--mapping -6,0,960" in text and "cache" in text


def test_the_family_is_cached_for_the_next_preview(src, tmp_path, capsys):
    cache = tmp_path / "cache"
    out = tmp_path / "o.png"
    assert _run(src, out, "--camera", "4,12,30,60", cache=cache) == 0
    assert "family cached" in capsys.readouterr().out
    first = read_image(out)
    assert len(list(cache.glob("*.family"))) == 1
    assert _run(src, out, "--camera", "4,12,30,60", cache=cache) == 0
    assert "family from the cache" in capsys.readouterr().out
    np.testing.assert_array_equal(read_image(out), first)
    assert _run(src, out, "--camera", "4,12,30,60") == 0
    said = capsys.readouterr().out
    assert "family cached" not in said and "from the cache" not in said


def test_the_default_cache_folder_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert command.default_cache_dir() == tmp_path / "terratheme" / "families"


@pytest.mark.parametrize("after, said", [(0.0, True), (60.0, False)])
def test_a_slow_first_step_says_it_is_compiling(monkeypatch, src, tmp_path, capsys, after, said):
    monkeypatch.setattr(command, "COMPILE_NOTE_AFTER", after)
    assert _run(src, tmp_path / "o.png", "--size", "8x6") == 0
    assert ("compiling the preview kernels" in capsys.readouterr().out) == said


def test_errors_exit_2(src, tmp_path, capsys):
    assert _run(src, tmp_path / "o.png", "--mapping", "1,0,0,0,1,0,0,0,0") == 2
    assert "singular" in capsys.readouterr().err
    assert _run(tmp_path / "missing.png", tmp_path / "o.png", "--camera", "4,12,30,60") == 2
    assert _run(src, src, "--camera", "4,12,30,60") == 2
    assert "also an input" in capsys.readouterr().err
    assert _run(src, tmp_path / "o.png", "--max-texture", "0") == 2
    with pytest.raises(SystemExit) as exc:
        main(["perspective", str(src), str(tmp_path / "o.png"), "--camera", "4,12"])
    assert exc.value.code == 2


def _tiny_project(tmp_path):
    from terratheme.core.model.grid import IndexGrid
    from terratheme.core.model.project import ThematicTexture, save_project
    from terratheme.core.themes.library import ThemeLibrary, flat_theme

    lib = ThemeLibrary([flat_theme("field", (200, 180, 40)), flat_theme("water", (20, 60, 200))])
    grid = IndexGrid(np.array([[0, 1, 0], [1, 0, 1], [0, 0, 1]], np.uint8), (8, 8))
    project = ThematicTexture(grid, lib)
    path = tmp_path / "tiny.ttproj"
    save_project(path, project)
    return path, project


def test_renders_a_project(tmp_path):
    from terratheme.core.render.project import render_project

    path, project = _tiny_project(tmp_path)
    texture = render_project(project)
    h, w = texture.shape[:2]
    out = tmp_path / "out.png"
    assert _run(path, out, "--method", "nearest", "--size", f"{w}x{h}",
                "--mapping", "1,0,0,0,1,0,0,0,1") == 0
    np.testing.assert_array_equal(read_image(out), texture)
    # the default view of the project
    assert _run(path, tmp_path / "default.png", "--size", "24x16") == 0
