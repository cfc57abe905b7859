"""Hostile project files: every one ends in a project or one line naming the file.

Regression tests for issue 16's project-file items, one per item; the
fuzzing is in ``test_hostile_project_fuzz.py``.
"""

from __future__ import annotations

import io
import json
import zipfile
import zlib

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.model.grid import MAX_CELL, IndexGrid, validate_cell
from terratheme.core.model.layers import LAYERS, LayerSpec, check_layer
from terratheme.core.model.project import (
    MAX_GRID_VERTICES,
    ThematicTexture,
    load_project,
    save_project,
)
from terratheme.core.themes.library import ThemeLibrary, flat_theme
from test_hostile_harness import ZipMember, craft_zip, npy_bytes


def _npy(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr)
    return buf.getvalue()


def _manifest(**changes) -> dict:
    m = {"format": "terratheme-project", "version": 1, "cell": [4, 4], "grid_shape": [2, 3],
         "themes": [{"name": "a", "colour": [1, 2, 3], "source": "", "texture": "themes/000.npy"}],
         "metadata": {}, "layers": []}
    m.update(changes)
    return m


def _members(manifest: dict | None = None, **arrays) -> list[ZipMember]:
    """A small valid project's members, with ``manifest`` and arrays replaced."""
    base = {"grid.npy": np.zeros((2, 3), np.uint8),
            "themes/000.npy": np.full((4, 4, 3), 9, np.uint8)}
    base.update({k.replace("__", "/").replace("_npy", ".npy"): v for k, v in arrays.items()})
    text = json.dumps(manifest or _manifest()).encode()
    return [ZipMember.of("manifest.json", text),
            *(ZipMember.of(name, v if isinstance(v, bytes) else _npy(v))
              for name, v in base.items())]


def _write(tmp_path, members: list[ZipMember], name: str = "p.ttproj"):
    path = tmp_path / name
    path.write_bytes(craft_zip(members))
    return path


def _small_project() -> ThematicTexture:
    rng = np.random.default_rng(0)
    lib = ThemeLibrary([flat_theme("water", (0, 0, 200), 4),
                        flat_theme("sand", (220, 200, 140), 3)])
    return ThematicTexture(IndexGrid(rng.integers(0, 2, (3, 4)), (8, 4)), lib,
                           {"source_photo": "x.jpg"},
                           photo=rng.integers(0, 256, (6, 5, 3), dtype=np.uint8),
                           scribbles=np.zeros((6, 5), np.uint8))


def test_the_crafted_baseline_loads(tmp_path):
    project = load_project(_write(tmp_path, _members()))
    assert project.grid.indices.shape == (2, 3) and project.grid.cell == (4, 4)


# -- regression tests, one per item of issue 16 -----------------------------

def test_npy_header_claiming_2_62_bytes_is_refused_before_allocating(tmp_path):
    huge = npy_bytes("{'descr': '|u1', 'fortran_order': False, 'shape': (2147483648, "
                     "2147483648), }")
    path = _write(tmp_path, _members(grid_npy=huge))
    with pytest.raises(CorruptFileError, match=r"p.ttproj: grid.npy declares shape .* but holds"):
        load_project(path)


def _deflated_zeros_after(header: bytes, n_mib: int) -> tuple[bytes, int]:
    """Raw deflate of ``header`` + ``n_mib`` MiB of zeros, and its CRC-32, made quickly:
    after a full flush every MiB of zeros deflates to the same bytes."""
    block = bytes(1 << 20)
    co = zlib.compressobj(9, zlib.DEFLATED, -15)
    head = co.compress(header) + co.flush(zlib.Z_FULL_FLUSH)
    first = co.compress(block) + co.flush(zlib.Z_FULL_FLUSH)
    again = co.compress(block) + co.flush(zlib.Z_FULL_FLUSH)
    assert first == again
    crc = zlib.crc32(header)
    for _ in range(n_mib):
        crc = zlib.crc32(block, crc)
    return head + first * n_mib + co.flush(), crc


def test_a_grid_that_inflates_to_1_gib_is_refused_by_its_declared_size(tmp_path):
    side = 1 << 15  # 32768 x 32768 uint8 = 1 GiB
    header = npy_bytes(f"{{'descr': '|u1', 'fortran_order': False, 'shape': ({side}, {side}), }}")
    stored, crc = _deflated_zeros_after(header, 1024)
    assert len(stored) < 2 << 20  # the file is about 1 MiB
    grid = ZipMember("grid.npy", stored, len(header) + (1 << 30), crc)
    members = [m for m in _members() if m.name != "grid.npy"] + [grid]
    path = _write(tmp_path, members)
    assert path.stat().st_size < 2 << 20 and (1 << 30) > MAX_GRID_VERTICES
    with pytest.raises(CorruptFileError, match=r"grid.npy declares 1,073,741,\d+ bytes, over the"):
        load_project(path)


@pytest.mark.parametrize(("manifest", "match"), [
    (_manifest(metadata=[1, 2]), "metadata must be a JSON object"),
    (_manifest(metadata="x"), "metadata must be a JSON object"),
    (_manifest(cell="sixteen"), r"cell size must be two whole numbers \(N, M\), got 'sixteen'"),
    (_manifest(cell=[16.5, 16]), "cell size must be two whole numbers"),
    (_manifest(cell=[True, 16]), "cell size must be two whole numbers"),
    (_manifest(cell=[MAX_CELL + 1, 1]), f"over the limit of {MAX_CELL} texels per side"),
    (_manifest(grid_shape=[3, 3]), "grid.npy is 2 x 3 but the manifest says 3 x 3"),
    (_manifest(grid_shape="2x3"), "grid_shape must be two whole numbers"),
    (_manifest(version=True), "bad format version"),
    (_manifest(themes=[]), "themes must be a list of 1..256"),
    (_manifest(themes=[{"name": "a", "colour": [1, 2, 300], "texture": "themes/000.npy"}]),
     "colour must be three whole numbers 0..255"),
    (_manifest(themes=[{"name": "a", "colour": [1, 2, 3], "texture": "grid.npy"}]),
     "texture 'grid.npy' is used twice"),
    (_manifest(themes=[{"name": 5, "colour": [1, 2, 3], "texture": "themes/000.npy"}]),
     "theme 0 name must be a non-empty string"),
    (_manifest(layers="photo"), "layers must be a list of names"),
    (_manifest(layers=["photo", "photo"]), "listed twice"),
    (_manifest(metadata={"georeference": {"ModelPixelScale": [1, "a", 0]}}),
     "georeference ModelPixelScale holds a value"),
    (_manifest(metadata={"georeference": {"ModelTiepoint": [0, 0, 0, 1, 2]}}),
     "georeference ModelTiepoint has 5 numbers"),
])
def test_bad_manifest_fields_are_one_line_errors(tmp_path, manifest, match):
    with pytest.raises(CorruptFileError, match=match) as exc:
        load_project(_write(tmp_path, _members(manifest)))
    assert "\n" not in str(exc.value) and str(exc.value).startswith(str(tmp_path))
    assert "('s', 'i'" not in str(exc.value)


def test_an_unknown_layer_is_a_newer_version(tmp_path):
    with pytest.raises(UnsupportedVersionError, match="layer 'heights' this terratheme"):
        load_project(_write(tmp_path, _members(_manifest(layers=["heights"]))))


@pytest.mark.parametrize("text", ['{"cell": [Infinity, 1]}', '{"cell": [NaN, 1]}',
                                  '{"cell": [1e999, 1]}', '-Infinity'])
def test_non_finite_numbers_in_the_manifest_are_refused(tmp_path, text):
    members = [ZipMember.of("manifest.json", text.encode()), *_members()[1:]]
    with pytest.raises(CorruptFileError, match="manifest.json is not valid JSON"):
        load_project(_write(tmp_path, members))


@pytest.mark.parametrize("depth", [40, 100_000])
def test_deeply_nested_json_is_refused(tmp_path, depth):
    text = json.dumps(_manifest())[:-1] + ', "x": ' + "[" * depth + "]" * depth + "}"
    members = [ZipMember.of("manifest.json", text.encode()), *_members()[1:]]
    with pytest.raises(CorruptFileError, match="manifest.json nests deeper than 32 levels"):
        load_project(_write(tmp_path, members))


def test_an_encrypted_member_is_refused(tmp_path):
    members = _members()
    members[1] = ZipMember(members[1].name, members[1].stored, members[1].file_size,
                           members[1].crc, flags=0x1)
    with pytest.raises(CorruptFileError, match="grid.npy is encrypted"):
        load_project(_write(tmp_path, members))


@pytest.mark.parametrize(("method", "name"), [(12, "bzip2"), (14, "lzma"), (99, "method 99")])
def test_an_unknown_compression_is_refused(tmp_path, method, name):
    members = _members()
    m = members[2]
    members[2] = ZipMember(m.name, m.stored, m.file_size, m.crc, method=method)
    with pytest.raises(CorruptFileError, match=f"themes/000.npy uses {name} compression"):
        load_project(_write(tmp_path, members))


def test_a_declared_size_the_bytes_cannot_hold_is_refused(tmp_path):
    members = _members()
    m = members[1]
    members[1] = ZipMember(m.name, m.stored, 50_000_000, m.crc)
    with pytest.raises(CorruptFileError, match="more than the data can hold"):
        load_project(_write(tmp_path, members))


def test_duplicate_members_are_refused(tmp_path):
    members = _members()
    with pytest.raises(CorruptFileError, match="the entry 'grid.npy' appears twice"):
        load_project(_write(tmp_path, [*members, members[1]]))


@pytest.mark.parametrize(("layer", "array", "match"), [
    ("photo", np.zeros(7, np.uint8), "photo.npy has shape"),
    ("photo", np.zeros((1,), np.uint8), "photo.npy has shape"),
    ("photo", np.zeros((4, 5, 3), np.float32), "photo.npy holds float32"),
    ("photo", np.zeros((4, 5, 4), np.uint8), r"photo layer must be \(H, W, 3\)"),
    ("photo", np.zeros((0, 5, 3), np.uint8), "photo layer has no pixels"),
    ("scribbles", np.zeros((4, 5, 1), np.uint8), "scribbles.npy has shape"),
    ("scribbles", np.zeros((4, 5), np.int64), "scribbles.npy holds int64"),
])
def test_layers_the_editor_cannot_show_are_refused(tmp_path, layer, array, match):
    members = _members(_manifest(layers=[layer]), **{f"{layer}_npy": array})
    with pytest.raises(CorruptFileError, match=match):
        load_project(_write(tmp_path, members))


def test_scribbles_must_match_the_photo(tmp_path):
    members = _members(_manifest(layers=["photo", "scribbles"]),
                       photo_npy=np.zeros((4, 5, 3), np.uint8),
                       scribbles_npy=np.zeros((5, 4), np.uint8))
    with pytest.raises(CorruptFileError, match="scribbles layer is 4 x 5 but the photo is 5 x 4"):
        load_project(_write(tmp_path, members))


def test_the_constructor_checks_layers_too():
    grid, lib = IndexGrid(np.zeros((2, 2), np.uint8)), ThemeLibrary([flat_theme("a", (1, 2, 3))])
    with pytest.raises(TerrathemeError, match=r"photo layer must be \(H, W, 3\)"):
        ThematicTexture(grid, lib, photo=np.zeros(5, np.uint8))
    with pytest.raises(TerrathemeError, match="metadata must be a dict"):
        ThematicTexture(grid, lib, metadata=[])


def test_a_new_layer_is_one_table_entry():
    spec = LayerSpec("colour_map", 3, np.dtype(np.uint8), same_size_as="grid")
    assert spec.member == "colour_map.npy"
    sizes = {"grid": (3, 4)}
    assert check_layer(spec, np.zeros((3, 4, 3), np.uint8), sizes).shape == (3, 4, 3)
    with pytest.raises(TerrathemeError, match="colour_map layer is 3 x 3 but the grid is 4 x 3"):
        check_layer(spec, np.zeros((3, 3, 3), np.uint8), sizes)
    assert [s.name for s in LAYERS] == ["photo", "scribbles"]


def test_save_refuses_what_load_would_refuse(tmp_path):
    project = _small_project()
    project.metadata["bad"] = float("nan")
    with pytest.raises(TerrathemeError, match="not JSON-serialisable"):
        save_project(tmp_path / "a.ttproj", project)
    project.metadata = {"georeference": {"ModelTransformation": [1.0] * 5}}
    with pytest.raises(TerrathemeError, match="ModelTransformation has 5 numbers"):
        save_project(tmp_path / "a.ttproj", project)
    deep: list = []
    node = deep
    for _ in range(40):
        node.append([])
        node = node[0]
    project.metadata = {"deep": deep}
    with pytest.raises(TerrathemeError, match="nests deeper"):
        save_project(tmp_path / "a.ttproj", project)
    assert not list(tmp_path.iterdir())


def test_cell_limits():
    assert validate_cell((MAX_CELL, 1)) == (MAX_CELL, 1)
    assert validate_cell(np.array([3, 5])) == (3, 5)
    with pytest.raises(TerrathemeError, match=f"1000000000 x 1 is over the limit of {MAX_CELL}"):
        validate_cell((1_000_000_000, 1))
    for bad in ("16", (16,), (1.5, 2), (True, 2), None):
        with pytest.raises(TerrathemeError, match="two whole numbers"):
            validate_cell(bad)


def test_a_round_trip_of_every_layer_still_works(tmp_path):
    project = _small_project()
    save_project(tmp_path / "a.ttproj", project)
    assert load_project(tmp_path / "a.ttproj") == project
    with zipfile.ZipFile(tmp_path / "a.ttproj") as zf:
        assert json.loads(zf.read("manifest.json"))["layers"] == ["photo", "scribbles"]


@pytest.mark.parametrize(("version", "error", "match"), [
    (6, UnsupportedVersionError, "newer"), (2**63, UnsupportedVersionError, "newer"),
    (0, CorruptFileError, "bad format version"), ("1", CorruptFileError, "bad format version"),
])
def test_version_bumps_are_named(tmp_path, version, error, match):
    with pytest.raises(error, match=match):
        load_project(_write(tmp_path, _members(_manifest(version=version))))


def test_a_version_of_4000_digits_is_a_short_line(tmp_path):
    with pytest.raises(UnsupportedVersionError, match="newer") as caught:
        load_project(_write(tmp_path, _members(_manifest(version=10**3999))))
    assert len(str(caught.value)) < 300
