"""The lead's model: IndexGrid, themes and the .ttproj project file."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.model.grid import IndexGrid, validate_cell, validate_indices
from terratheme.core.model.project import ThematicTexture, load_project, save_project
from terratheme.core.themes.library import (
    Theme,
    ThemeLibrary,
    flat_theme,
    read_theme_library,
    validate_texture,
)


def _project(photo: bool = True) -> ThematicTexture:
    rng = np.random.default_rng(0)
    lib = ThemeLibrary([
        Theme("water", (0, 0, 200), rng.integers(0, 256, (8, 6, 3), dtype=np.uint8)),
        Theme("sand", (220, 200, 140), rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)),
    ])
    grid = IndexGrid(rng.integers(0, 2, (4, 5)), (8, 4))
    return ThematicTexture(
        grid, lib, {"source_photo": "x.jpg", "georeference": {"crs": "EPSG:32640"}},
        photo=rng.integers(0, 256, (16, 32, 3), dtype=np.uint8) if photo else None,
        scribbles=np.zeros((16, 32), np.uint8) if photo else None,
    )


def test_grid_sizes() -> None:
    g = IndexGrid(np.zeros((4, 6), int), (8, 5))
    assert g.cells_shape == (3, 5)
    assert g.texture_size == (40, 15)
    assert g.indices.dtype == np.uint8
    assert g == g.copy() and g.copy() is not g


@pytest.mark.parametrize("photo", [True, False])
def test_project_round_trip(tmp_path, photo: bool) -> None:
    p = _project(photo)
    save_project(tmp_path / "a.ttproj", p)
    q = load_project(tmp_path / "a.ttproj")
    assert q == p
    assert q.grid.cell == (8, 4)
    assert q.metadata["georeference"]["crs"] == "EPSG:32640"


def test_project_save_is_atomic(tmp_path) -> None:
    p = _project()
    target = tmp_path / "a.ttproj"
    save_project(target, p)
    before = target.read_bytes()
    p.metadata["bad"] = object()  # not JSON: the save must fail and leave the old file
    with pytest.raises(TerrathemeError, match="JSON"):
        save_project(target, p)
    assert target.read_bytes() == before
    assert [f.name for f in tmp_path.iterdir()] == ["a.ttproj"]


def test_damaged_project(tmp_path) -> None:
    save_project(tmp_path / "a.ttproj", _project())
    data = (tmp_path / "a.ttproj").read_bytes()
    (tmp_path / "trunc.ttproj").write_bytes(data[: len(data) // 2])
    with pytest.raises(CorruptFileError):
        load_project(tmp_path / "trunc.ttproj")
    (tmp_path / "junk.ttproj").write_bytes(b"not a zip at all")
    with pytest.raises(CorruptFileError, match="not a terratheme project"):
        load_project(tmp_path / "junk.ttproj")
    # Flip bytes inside the stored grid member: the CRC check catches it.
    with zipfile.ZipFile(tmp_path / "a.ttproj") as zf:
        info = zf.getinfo("grid.npy")
        start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    bad = bytearray(data)
    for i in range(start + 5, start + 15):
        bad[i] ^= 0xFF
    (tmp_path / "flip.ttproj").write_bytes(bytes(bad))
    with pytest.raises(CorruptFileError):
        load_project(tmp_path / "flip.ttproj")
    with pytest.raises(TerrathemeError, match="no such project"):
        load_project(tmp_path / "missing.ttproj")


def _rewrite(src, dst, manifest_change=None, drop=None, replace=None) -> None:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            if item.filename == drop:
                continue
            data = zin.read(item.filename)
            if item.filename == "manifest.json" and manifest_change:
                m = json.loads(data)
                manifest_change(m)
                data = json.dumps(m).encode()
            if replace and item.filename in replace:
                data = replace[item.filename]
            zout.writestr(item.filename, data)


def test_newer_version_and_bad_manifests(tmp_path) -> None:
    src = tmp_path / "a.ttproj"
    save_project(src, _project())
    _rewrite(src, tmp_path / "v9.ttproj", lambda m: m.update(version=9))
    with pytest.raises(UnsupportedVersionError, match="newer"):
        load_project(tmp_path / "v9.ttproj")
    _rewrite(src, tmp_path / "fmt.ttproj", lambda m: m.update(format="other"))
    with pytest.raises(CorruptFileError, match="format tag"):
        load_project(tmp_path / "fmt.ttproj")
    _rewrite(src, tmp_path / "nogrid.ttproj", drop="grid.npy")
    with pytest.raises(CorruptFileError, match="grid.npy"):
        load_project(tmp_path / "nogrid.ttproj")
    _rewrite(src, tmp_path / "nocell.ttproj", lambda m: m.pop("cell"))
    with pytest.raises(CorruptFileError, match="cell"):
        load_project(tmp_path / "nocell.ttproj")
    # A grid index without a theme.
    import io

    buf = io.BytesIO()
    np.save(buf, np.full((4, 5), 7, np.uint8))
    _rewrite(src, tmp_path / "idx.ttproj", replace={"grid.npy": buf.getvalue()})
    with pytest.raises(CorruptFileError, match="theme index 7"):
        load_project(tmp_path / "idx.ttproj")


def test_validate_indices_errors() -> None:
    with pytest.raises(TerrathemeError, match="negative"):
        validate_indices(np.array([[0, -2], [0, 0]]))
    with pytest.raises(TerrathemeError, match="2-D"):
        validate_indices(np.zeros(5, int))
    with pytest.raises(TerrathemeError, match="at least 2 x 2"):
        validate_indices(np.zeros((1, 1), int))
    with pytest.raises(TerrathemeError, match="integers"):
        validate_indices(np.array([["a", "b"], ["c", "d"]]))
    with pytest.raises(TerrathemeError, match="256 themes"):
        validate_indices(np.array([[0, 300], [0, 0]]))
    with pytest.raises(TerrathemeError, match="only 2 themes"):
        validate_indices(np.array([[0, 2], [0, 0]]), n_themes=2)
    assert validate_indices(np.array([[0.0, 1.0], [1.0, 0.0]])).dtype == np.uint8
    with pytest.raises(TerrathemeError, match="cell size"):
        validate_cell((4, -1))
    with pytest.raises(TerrathemeError, match="cell size"):
        validate_cell("ab")


def test_themes_and_library() -> None:
    with pytest.raises(TerrathemeError, match="empty"):
        validate_texture(np.zeros((0, 3, 3), np.uint8))
    with pytest.raises(TerrathemeError, match="RGB"):
        validate_texture(np.zeros((3, 3, 2), np.uint8))
    assert validate_texture(np.ones((2, 2, 4), np.float32)).max() == 255
    assert validate_texture(np.full((2, 2, 3), 65535, np.uint16)).max() == 255
    with pytest.raises(TerrathemeError, match="NaN"):
        validate_texture(np.full((2, 2, 3), np.nan))
    with pytest.raises(TerrathemeError, match="colour"):
        Theme("x", (0, 0, 300), np.zeros((2, 2, 3), np.uint8))
    with pytest.raises(TerrathemeError, match="name"):
        Theme(" ", (0, 0, 0), np.zeros((2, 2, 3), np.uint8))
    lib = ThemeLibrary([flat_theme("A", (1, 2, 3)), flat_theme("b", (4, 5, 6))])
    assert lib.index_of("a") == 0 and lib.index_of("B") == 1
    with pytest.raises(TerrathemeError, match="unknown theme"):
        lib.index_of("c")
    with pytest.raises(TerrathemeError, match="already"):
        lib.append(flat_theme("a", (0, 0, 0)))
    with pytest.raises(TerrathemeError, match="no theme with index"):
        lib[5]
    assert lib.select(["b", "a"]).names == ["b", "A"]
    np.testing.assert_array_equal(lib.colours, [[1, 2, 3], [4, 5, 6]])
    with pytest.raises(TerrathemeError, match="at least one theme"):
        ThematicTexture(IndexGrid(np.zeros((2, 2), int)), ThemeLibrary())


def test_read_theme_library_errors(tmp_path) -> None:
    with pytest.raises(TerrathemeError, match="themes.json"):
        read_theme_library(tmp_path)
    (tmp_path / "themes.json").write_text("{not json")
    with pytest.raises(CorruptFileError, match="theme list"):
        read_theme_library(tmp_path)
    (tmp_path / "themes.json").write_text(json.dumps({"version": 1, "themes": [{"name": "a"}]}))
    with pytest.raises(CorruptFileError, match="lacks"):
        read_theme_library(tmp_path)
