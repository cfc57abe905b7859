"""Hostile copies of terratheme's own formats (projects, packed layers, theme
libraries, classifier files, exports read back): each ends in one line naming the
problem, with work bounded by the file, and leaves the input as it was.

Each section is the regression test of one failure a fuzz campaign of these readers
found (what it was, in the comment above it), plus a full-disk check that was already
handled; the broader fuzzing lives in the ``test_hostile_*`` files of each format.
"""

from __future__ import annotations

import io
import json
import struct
import zlib

import numpy as np
import pytest
from hostile_fuzz import REPO, check_refused, run_cli
from terratheme.core.classify.model_file import read_model_bytes
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.exchange.layout import world_frame
from terratheme.core.exchange.plan import safe_name
from terratheme.core.io.archive import open_archive
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, load_project, save_project
from terratheme.core.packing import PackedLayer, TiledLayer, layer_info, pack
from terratheme.core.packing import tiled_format as tiled
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.themes.library import ThemeLibrary, flat_theme, read_theme_library
from test_hostile_harness import ZipMember, check_bounded, craft_zip, shared_reader


def _npy(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr)
    return buf.getvalue()


def _deflate(data: bytes) -> bytes:
    co = zlib.compressobj(9, zlib.DEFLATED, -15)
    return co.compress(data) + co.flush()


def _local(name: bytes, crc: int, stored: int, size: int, extra: int) -> bytes:
    return struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0, crc, stored, size,
                       len(name), extra) + name


def _shared_zip(plain: dict[str, bytes], shared: list[str], data: bytes) -> bytes:
    """A ZIP whose ``plain`` members are honest and whose ``shared`` members' local
    headers all skip (by their extra-field length) onto one deflate stream of ``data``:
    the file holds that stream once, a reader that allows it decodes it once a member."""
    body, entries = bytearray(), []
    for name, raw in plain.items():
        stored, crc = _deflate(raw), zlib.crc32(raw)
        entries.append((name.encode(), crc, len(stored), len(raw), len(body)))
        body += _local(name.encode(), crc, len(stored), len(raw), 0) + stored
    stored, crc = _deflate(data), zlib.crc32(data)
    start = len(body) + sum(30 + len(n.encode()) for n in shared)
    for name in shared:
        head = len(body) + 30 + len(name.encode())
        entries.append((name.encode(), crc, len(stored), len(data), len(body)))
        body += _local(name.encode(), crc, len(stored), len(data), start - head)
    body += stored
    central = b"".join(
        struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0, crc, n_stored,
                    size, len(name), 0, 0, 0, 0, 0, offset) + name
        for name, crc, n_stored, size, offset in entries)
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(entries), len(entries),
                      len(central), len(body), 0)
    return bytes(body + central + end)


def _shared_texture_project(n_themes: int, side: int) -> bytes:
    names = [f"themes/{k:03d}.npy" for k in range(n_themes)]
    manifest = {"format": "terratheme-project", "version": 1, "cell": [1, 1],
                "grid_shape": [2, 2], "metadata": {}, "layers": [],
                "themes": [{"name": f"t{k}", "colour": [k, 0, 0], "texture": name}
                           for k, name in enumerate(names)]}
    plain = {"manifest.json": json.dumps(manifest).encode(),
             "grid.npy": _npy(np.zeros((2, 2), np.uint8))}
    return _shared_zip(plain, names, _npy(np.zeros((side, side, 3), np.uint8)))


# -- ZIP members sharing one deflate stream (projects, classifier files) ------
# Was: 256 theme textures of 4096² over one 76 KB stream, a 78 KB project, were each
# decoded (12 GiB asked; 2.1 GB resident and 6 s before "not enough memory" under a
# 3 GB ulimit, far past deflate's 1032:1 bound). Now the directory is refused.

def test_members_sharing_one_stream_are_refused(tmp_path):
    path = tmp_path / "shared.ttproj"
    path.write_bytes(_shared_texture_project(3, 8))
    with pytest.raises(CorruptFileError, match="overlaps the next entry"):
        load_project(path)


def test_member_whose_data_runs_into_the_next_is_refused():
    inner = _npy(np.zeros((4, 4), np.uint8))
    archive = bytearray(_shared_zip({"a.npy": inner, "b.npy": inner}, [], b""))
    # a.npy's stored size now reaches over b.npy's local header (a "quoted" overlap)
    central = archive.index(b"PK\x01\x02")
    struct.pack_into("<I", archive, central + 20, 120)
    with pytest.raises(CorruptFileError, match="a.npy overlaps the next entry"):
        open_archive(bytes(archive), "x.zip", kind="test archive", max_members=4)


def test_shared_stream_project_is_one_line_through_the_cli(tmp_path):
    path = tmp_path / "shared.ttproj"
    data = _shared_texture_project(256, 64)
    path.write_bytes(data)
    check_refused(run_cli("info", path), "shared.ttproj", "overlaps the next entry")
    assert path.read_bytes() == data


# -- tiled packed layers: a tile index whose sum wraps 2^64 -------------------
# Was: lengths 2^63-1, 2^63-1, 40, T-38 (offsets running on modulo 2^64) passed the
# "end to end" check in int64 arithmetic; info and unpack then asked read() for 2^63
# bytes: an OverflowError traceback, exit 1. Now the index is refused.

def _wrapped_index_container() -> bytes:
    img = (np.arange(128 * 128).reshape(128, 128) // 300 % 4).astype(np.uint8)
    data = bytearray(pack(img, tile_bits=6).to_bytes())
    head = tiled.read_tiled_header(bytes(data), name="t", file_bytes=len(data))
    assert head.tiles == 4
    lengths = [2**63 - 1, 2**63 - 1, 40, head.tile_bytes - 38]
    offset = 0
    for i, n in enumerate(lengths):
        struct.pack_into("<QQ", data, head.index_at + 16 * i, offset, n)
        offset = (offset + n) % 2**64
    assert offset == head.tile_bytes  # the lengths do add up, modulo 2^64
    struct.pack_into("<I", data, head.tiles_at - 4, zlib.crc32(data[:head.tiles_at - 4]))
    return bytes(data)


def test_tile_index_wrapping_2_64_is_refused():
    with pytest.raises(CorruptFileError, match="tile index does not run end to end"):
        TiledLayer.from_bytes(_wrapped_index_container(), name="t")


@pytest.mark.parametrize("command", ["info", "unpack"])
def test_tile_index_wrapping_2_64_is_one_line(tmp_path, command):
    path, out = tmp_path / "w.ttpack", tmp_path / "w.png"
    data = _wrapped_index_container()
    path.write_bytes(data)
    args = [command, path] + ([out] if command == "unpack" else [])
    check_refused(run_cli(*args), "w.ttpack", "tile index does not run end to end")
    assert path.read_bytes() == data and sorted(tmp_path.iterdir()) == [path]


# -- an export read back: the output is the project the export carries --------
# Was: `new --from export EXP EXP/terratheme_project.ttproj` (or a link to it) replaced
# the carried project, an input, with a re-saved copy and exited 0: only the manifest
# was checked against the output. Now the carried project is an input too.

@pytest.fixture(scope="module")
def export_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (4, 4)),
                              ThemeLibrary([flat_theme("water", (0, 0, 200), 4),
                                            flat_theme("sand", (220, 200, 140), 4)]))
    save_project(folder / "p.ttproj", project)
    proc = run_cli("export", folder / "p.ttproj", folder / "exp", "--engine", "unity")
    assert proc.returncode == 0, proc.stderr
    return folder / "exp"


@pytest.mark.parametrize("output", ["terratheme_project.ttproj", "link.ttproj"])
def test_new_from_export_never_writes_over_the_carried_project(export_folder, output):
    carried = export_folder / "terratheme_project.ttproj"
    before = carried.read_bytes()
    link = export_folder / "link.ttproj"
    if not link.exists():
        link.symlink_to(carried.name)
    check_refused(run_cli("new", "--from", "export", export_folder, export_folder / output),
                  "is also an input")
    assert carried.read_bytes() == before


# -- a project's georeference beyond floating point, exported -----------------
# Was: a geographic georeference (GeoKey 1024 = 2) whose centre latitude overflows
# gave "ValueError: math domain error" from math.cos, a traceback, exit 1; pixel sizes
# of 1e308 (or 1e306, times Unreal's 100 cm and a texture's side) wrote "Infinity" and
# "NaN" into the manifest, which no JSON reader (ours included) loads, exit 0; a
# subnormal pixel size (5e-324) gave a ZeroDivisionError traceback in Unreal's. Now the
# frame is checked finite, the manifest is written with finite numbers only, and the
# export is one line with no file written.

_GEOGRAPHIC = {"ModelPixelScale": [1e308, 1e308, 0], "ModelTiepoint": [0, 0, 0, 1e308, 1e308, 0],
               "GeoKeyDirectory": [1, 1, 0, 1, 1024, 0, 1, 2]}


def _huge(v: float) -> dict:
    return {"ModelPixelScale": [v, v, 0], "ModelTiepoint": [0, 0, 0, v, -v, 0]}


@pytest.mark.parametrize("georeference, match", [
    (_GEOGRAPHIC, "beyond the poles"),
    ({**_GEOGRAPHIC, "ModelPixelScale": [1e-3, 1e-3, 0], "ModelTiepoint": [0, 0, 0, 0, 95, 0]},
     "beyond the poles"),
    (_huge(1e308), "beyond the range of floating-point numbers"),
    ({**_huge(1.0), "ModelPixelScale": [5e-324, 1, 0]}, "beyond the range of floating-point"),
])
def test_world_frame_beyond_floating_point_is_refused(georeference, match):
    with pytest.raises(TerrathemeError, match=match):
        world_frame(georeference, (24, 8))


@pytest.mark.parametrize("georeference, match", [
    (_GEOGRAPHIC, "beyond the poles"), (_huge(1e308), "floating-point"),
    (_huge(1e306), "not JSON-serialisable"),
    ({**_huge(1.0), "ModelPixelScale": [5e-324, 1, 0]}, "floating-point")])
def test_export_of_a_georeference_beyond_floating_point_is_one_line(tmp_path, georeference,
                                                                     match):
    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (8, 4)),
                              ThemeLibrary([flat_theme("water", (0, 0, 200), 4),
                                            flat_theme("sand", (220, 200, 140), 4)]),
                              {"georeference": georeference})
    save_project(tmp_path / "g.ttproj", project)
    out = tmp_path / "exp"
    out.mkdir()
    check_refused(run_cli("export", tmp_path / "g.ttproj", out, "--engine", "unreal"), match)
    assert list(out.iterdir()) == []


# -- a project's render style: noise features per cell near zero --------------
# Was: metadata {"render": {"boundary": {"features": 5e-324}}} gave "OverflowError:
# cannot convert float infinity to integer" and 1e-300 a numba typing error (a 300-digit
# lattice), both tracebacks with exit 1, from render, export and the editor's preview.
# Now the lattice stops at 2^31 texels (the noise is one value across any texture).

@pytest.mark.parametrize("features", [5e-324, 1e-300, 1e-9])
def test_a_vanishing_noise_feature_count_gives_a_bounded_lattice(features):
    params = BoundaryOptions(features=features).parameters(16, 16)
    assert 2 <= params.lattice <= 2**31


def test_a_project_asking_for_a_vanishing_feature_count_renders(tmp_path):
    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (8, 4)),
                              ThemeLibrary([flat_theme("water", (0, 0, 200), 4),
                                            flat_theme("sand", (220, 200, 140), 4)]),
                              {"render": {"boundary": {"features": 1e-300}}})
    save_project(tmp_path / "b.ttproj", project)
    proc = run_cli("render", tmp_path / "b.ttproj", tmp_path / "b.png")
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert (tmp_path / "b.png").stat().st_size > 0


# Was: a render style's {"seed": 1.5}, {"noise": 90.5} or {"height": true} rendered
# (the fractions and the boolean taken as they came), and {"width": "3"} gave a Python
# comparison message. Now each names the field and what it must be, and the CLI stops.

@pytest.mark.parametrize("field, value, must", [("seed", 1.5, "a whole number"),
                                                ("noise", 90.5, "a whole number"),
                                                ("height", True, "a whole number"),
                                                ("width", "3", "a number")])
def test_a_render_style_field_of_the_wrong_type_is_one_line(tmp_path, field, value, must):
    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (8, 4)),
                              ThemeLibrary([flat_theme("water", (0, 0, 200), 4),
                                            flat_theme("sand", (220, 200, 140), 4)]),
                              {"render": {"boundary": {field: value}}})
    save_project(tmp_path / "b.ttproj", project)
    proc = run_cli("render", tmp_path / "b.ttproj", tmp_path / "b.png")
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-2000:]
    assert f"boundary {field} must be {must}" in lines[0]
    assert not (tmp_path / "b.png").exists()


# Was: `new --from export` given a pipe named like a manifest said "no such export folder
# or manifest", though the path is there. Now it says what the path is.

def test_an_export_manifest_that_is_a_pipe_is_named_so(tmp_path):
    import os

    fifo = tmp_path / "terratheme_unity.json"
    os.mkfifo(fifo)
    proc = run_cli("new", "--from", "export", fifo, tmp_path / "p.ttproj")
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-2000:]
    assert "is a pipe, not an export manifest" in lines[0]
    assert not (tmp_path / "p.ttproj").exists()


# Was: a folder named like a manifest said "no export manifests (terratheme_*.json) in the
# folder", and an export folder holding one counted it as its manifest.

def test_an_export_manifest_that_is_a_folder_is_named_so(tmp_path):
    folder = tmp_path / "export" / "terratheme_unity.json"
    folder.mkdir(parents=True)
    proc = run_cli("new", "--from", "export", folder, tmp_path / "p.ttproj")
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-2000:]
    assert "terratheme_unity.json: is a folder, not an export manifest" in lines[0]
    proc = run_cli("new", "--from", "export", folder.parent, tmp_path / "p.ttproj")
    assert proc.returncode == 2 and "no export manifests" in proc.stderr
    assert not (tmp_path / "p.ttproj").exists()


# -- text from a file reaching the terminal ------------------------------------
# Was: a project whose theme name held "\x1b]0;pwned\x07...\x1b[2K\rFAKE: success\n"
# loaded; `new --from export` printed the carried project's theme names raw, so the
# file set the terminal's title, erased the line and printed lines of its own; `info`
# printed metadata["source_photo"] raw the same way. Now a theme name must be
# printable text (as themes.json and legends already require) and `info` shows text
# with control characters as a quoted literal.

_ESCAPES = "wa\x1b]0;pwned\x07ter\x1b[2K\rFAKE: success\nsecond line"


def _crafted_project(name: str, metadata: dict) -> bytes:
    manifest = {"format": "terratheme-project", "version": 1, "cell": [4, 4],
                "grid_shape": [2, 2], "metadata": metadata, "layers": [],
                "themes": [{"name": name, "colour": [1, 2, 3], "texture": "themes/000.npy"}]}
    return _shared_zip({"manifest.json": json.dumps(manifest).encode(),
                        "grid.npy": _npy(np.zeros((2, 2), np.uint8)),
                        "themes/000.npy": _npy(np.zeros((4, 4, 3), np.uint8))}, [], b"")


def test_a_theme_name_with_control_characters_is_refused(tmp_path):
    path = tmp_path / "esc.ttproj"
    path.write_bytes(_crafted_project(_ESCAPES, {}))
    with pytest.raises(CorruptFileError, match="is not one line of printable text"):
        load_project(path)
    path.write_bytes(_crafted_project("water", {}))
    assert load_project(path).library.names == ["water"]


def test_info_never_prints_a_control_character_from_the_file(tmp_path):
    path = tmp_path / "meta.ttproj"
    path.write_bytes(_crafted_project("water", {"source_photo": "x\x1b[2J.jpg"}))
    proc = run_cli("info", path)
    assert proc.returncode == 0, proc.stderr
    assert "\x1b" not in proc.stdout and "source_photo: 'x\\x1b[2J.jpg'" in proc.stdout


# -- a classifier file: a ZIP inside a ZIP -------------------------------------
# Was: a 4.7 KB model file whose forest.npz (2 MB, deflated again to 4 KB) holds a
# value.npy of 2 GiB of zeros read it whole before the forest's shapes were checked:
# 13 s and 2.3 GB resident (32 GiB allowed by the per-array ceiling), two deflate
# ratios multiplied. Now the arrays may declare at most 1032 x the model file's size.

def _nested_model(value_rows: int) -> bytes:
    """A model file (meta.json of the shipped aerial.model) whose forest.npz holds tiny
    arrays and a ``(value_rows, 2)`` float64 value.npy of zeros, deflated twice."""
    import zipfile

    with zipfile.ZipFile(REPO / "models" / "aerial.model") as zf:
        meta = zf.read("meta.json")
    arrays = {"classes": np.array([1, 2]), "roots": np.array([0]), "feature": np.array([-1]),
              "threshold": np.zeros(1), "left": np.array([-1]), "right": np.array([-1]),
              "value": np.zeros((value_rows, 2))}
    npz = _shared_zip({f"{k}.npy": _npy(v) for k, v in arrays.items()}, [], b"")
    return _shared_zip({"meta.json": meta, "forest.npz": npz}, [], b"")


def test_forest_arrays_beyond_one_deflate_of_the_file_are_refused_unread():
    data = _nested_model(1 << 22)  # 64 MiB of value from a file of a few KB
    assert len(data) < 64 << 10
    with pytest.raises(CorruptFileError, match="arrays declare .* more than 1032 times"):
        read_model_bytes(data, "m.model")


def test_the_shipped_model_is_within_the_forest_budget():
    assert read_model_bytes((REPO / "models" / "aerial.model").read_bytes(), "aerial.model")


# -- a long theme name in an export's file names -------------------------------
# Was: a project may name a theme with up to 4096 characters, and every export but the
# GIS one put the whole name into a file name: "theme_00_aaa...a.png: File name too long"
# (exit 2) for a project that loads and renders. Now the name in a file is cut to 64.

def test_safe_names_fit_a_file_name():
    assert safe_name("a" * 4096) == "a" * 64
    assert safe_name("rock" + "!" * 100 + "x" * 100) == "rock_" + "x" * 59
    assert safe_name("a" * 63 + " b") == "a" * 63  # no trailing "_" left by the cut


@pytest.mark.parametrize("engine", ["unity", "unreal"])
def test_a_theme_with_a_long_name_exports(tmp_path, engine):
    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (8, 4)),
                              ThemeLibrary([flat_theme("w" * 300, (0, 0, 200), 4),
                                            flat_theme("sand", (220, 200, 140), 4)]))
    save_project(tmp_path / "long.ttproj", project)
    proc = run_cli("export", tmp_path / "long.ttproj", tmp_path / "exp", "--engine", engine)
    assert proc.returncode == 0, proc.stderr[-500:]
    names = [p.name for p in (tmp_path / "exp").iterdir()]
    assert any(("w" * 64) in n for n in names) and max(map(len, names)) < 100


# -- a full disk while a format's writer runs ---------------------------------
# Already handled (no fix): each writer writes a temporary and renames it, so a write
# that fails with ENOSPC leaves the old file byte for byte and no temporary, and the
# error names the output. Simulated by failing every write after the first 64 bytes.

def _full_disk_after(monkeypatch, allowed: int) -> None:
    import builtins
    import errno

    real_open = builtins.open

    class Filling:
        def __init__(self, fh):
            self._fh, self._left = fh, allowed

        def write(self, data):
            if len(data) > self._left:
                raise OSError(errno.ENOSPC, "No space left on device")
            self._left -= len(data)
            return self._fh.write(data)

        def __getattr__(self, name):
            return getattr(self._fh, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return self._fh.__exit__(*exc)

    def opening(file, mode="r", *args, **kwargs):
        fh = real_open(file, mode, *args, **kwargs)
        return Filling(fh) if "w" in mode and ".tt-" in str(file) else fh

    monkeypatch.setattr(builtins, "open", opening)
    monkeypatch.setattr("io.open", opening)


def _writers(tmp_path):
    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (8, 4)),
                              ThemeLibrary([flat_theme("water", (0, 0, 200), 16),
                                            flat_theme("sand", (220, 200, 140), 16)]))
    img = (np.arange(128 * 128).reshape(128, 128) // 300 % 4).astype(np.uint8)
    return {"project": (tmp_path / "p.ttproj", lambda p: save_project(p, project)),
            "layer": (tmp_path / "l.ttpack", lambda p: pack(img).save(p)),
            "tiled": (tmp_path / "t.ttpack", lambda p: pack(img, tile_bits=6).save(p))}


@pytest.mark.parametrize("kind", ["project", "layer", "tiled"])
def test_a_full_disk_keeps_the_old_file_and_leaves_no_temporary(tmp_path, monkeypatch, kind):
    path, write = _writers(tmp_path)[kind]
    path.write_bytes(b"the old file")
    with monkeypatch.context() as patch:
        _full_disk_after(patch, 64)
        with pytest.raises(OSError, match="No space left") as info:
            write(path)
    assert info.value.filename == str(path)
    assert path.read_bytes() == b"the old file"
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    write(path)  # with room again, the same writer succeeds
    assert path.stat().st_size > 64


# -- a full disk while an export writes ---------------------------------------
# Was: the files were taken back, but the export folder (and its missing parents and the
# engine's subfolders) stayed behind, empty. Now only folders that were there before stay.

@pytest.mark.parametrize("engine", ["unity", "unreal", "godot", "geotiff"])
def test_a_failed_export_leaves_no_folder_it_made(tmp_path, monkeypatch, engine):
    from terratheme.core.exchange import Engine, ExportOptions, plan_export, write_export

    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (8, 8)),
                              ThemeLibrary([flat_theme("water", (0, 0, 200), 16),
                                            flat_theme("sand", (220, 200, 140), 16)]))
    plan = plan_export(project, ExportOptions(engine=Engine(engine)))
    kept = tmp_path / "kept"
    (kept / "old").mkdir(parents=True)
    (kept / "old" / "notes.txt").write_text("mine")
    for folder in (tmp_path / "new" / "deeper" / "exp", kept):
        with monkeypatch.context() as patch:
            _full_disk_after(patch, 64)
            with pytest.raises(OSError, match="No space left"):
                write_export(project, plan, folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept"]
    assert sorted(str(p.relative_to(kept)) for p in kept.rglob("*")) == ["old", "old/notes.txt"]
    assert (kept / "old" / "notes.txt").read_text() == "mine"
    # With room again the same export is written whole.
    written = write_export(project, plan, tmp_path / "new" / "deeper" / "exp")
    assert written and all(p.is_file() for p in written)


def test_a_full_disk_in_export_names_the_file_and_leaves_no_folder(tmp_path, monkeypatch,
                                                                   capsys):
    # Was: "error: No space left on device" (no file named), and the folders the command
    # made for its outputs (the export folder, its new parents, Unity's Editor/ and
    # Shaders/) stayed behind, empty.
    from terratheme.app.cli import main

    project = ThematicTexture(IndexGrid(np.array([[0, 1, 1], [1, 0, 0]], np.uint8), (8, 8)),
                              ThemeLibrary([flat_theme("water", (0, 0, 200), 16),
                                            flat_theme("sand", (220, 200, 140), 16)]))
    save_project(tmp_path / "p.ttproj", project)
    out = tmp_path / "new" / "exp"
    with monkeypatch.context() as patch:
        _full_disk_after(patch, 64)
        status = main(["export", str(tmp_path / "p.ttproj"), str(out), "--engine", "unity"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(lines) == 1
    assert str(out) in lines[0] and "No space left" in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.ttproj"]


# -- theme names that one engine layer name stands for ------------------------
# Was: "rock!" and "rock?" (or two long names sharing their first 64 characters) were
# both exported as the layer "rock": Unity's importer creates "rock.terrainlayer" once
# per layer, so the second replaced the first, and Unreal got one layer name twice.
# Now a name already taken gets its theme's index appended.

@pytest.mark.parametrize("engine", ["unity", "unreal"])
def test_engine_layer_names_are_distinct(tmp_path, engine):
    names = ["rock!", "rock?", "rock_02", "rock"]
    project = ThematicTexture(IndexGrid(np.array([[0, 1, 2], [3, 0, 0]], np.uint8), (8, 4)),
                              ThemeLibrary([flat_theme(n, (k, 0, 0), 4)
                                            for k, n in enumerate(names)]))
    save_project(tmp_path / "n.ttproj", project)
    proc = run_cli("export", tmp_path / "n.ttproj", tmp_path / "exp", "--engine", engine)
    assert proc.returncode == 0, proc.stderr[-500:]
    manifest = json.loads((tmp_path / "exp" / f"terratheme_{engine}.json").read_text())
    layers = [layer["name"] for layer in manifest["layers"]]
    assert layers == ["rock", "rock_01", "rock_02", "rock_03"]


# -- a large file that is no packed layer (or a layer with a tail) -------------
# Was: PackedLayer.load and info read the whole file before looking at its header: a
# 3 GiB file with a layer's first 64 bytes (or none) took 11-14 s and 3.2 GB resident
# to be called "not a packed layer" / "bytes after the data". Now the header is read
# and checked against the file's size first (0.4 s, 75 MB).

@pytest.mark.parametrize("head", [b"", b"layer"])
@pytest.mark.parametrize("reader", ["load", "info"])
def test_a_large_file_is_refused_from_its_header(tmp_path, head, reader):
    import tracemalloc

    path = tmp_path / "big.ttpack"
    with open(path, "wb") as fh:
        if head:
            img = (np.arange(128 * 128).reshape(128, 128) // 300 % 4).astype(np.uint8)
            fh.write(pack(img).to_bytes()[:64])
        fh.truncate(256 << 20)  # sparse: no disk space used
    tracemalloc.start()
    try:
        with pytest.raises(CorruptFileError, match="unexpected bytes|not a terratheme packed"):
            PackedLayer.load(path) if reader == "load" else layer_info(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20, peak


# -- a saved project with many themes and a tiled colour map -------------------
# Was: the reader took at most MAX_THEMES + 64 = 320 members, but a tiled colour map
# adds one member a tile: 250 themes and a 286720 x 1 WebP map (70 tiles) saved fine
# and then would not load ("322 entries, more than a terratheme project has"). Now a
# project holds up to 65536 tiles more, and saving refuses a map beyond that.

def test_a_saved_project_with_many_themes_and_map_tiles_loads(tmp_path):
    grid = IndexGrid(np.zeros((2, 71), np.uint8), (4096, 1))
    w, h = grid.texture_size
    cmap = ColourMap.encode(np.full((h, w, 3), 128, np.uint8), 1, "webp", 90)
    assert len(cmap.tiles) == 70
    project = ThematicTexture(grid, ThemeLibrary([flat_theme(f"t{k}", (k, 0, 0), 4)
                                                  for k in range(250)]), colour_map=cmap)
    save_project(tmp_path / "many.ttproj", project)
    back = load_project(tmp_path / "many.ttproj")
    assert len(back.library) == 250 and back.colour_map.tiles == cmap.tiles



def test_a_name_twice_among_60000_entries_is_found_in_linear_time(tmp_path):
    # With room for a tiled map's members, the duplicate finder must not be quadratic
    # (names.count per name: 52 s of CPU for 60001 names, past the 2 s bound).
    path = tmp_path / "dup.ttproj"
    names = [f"m{k:05d}" for k in range(60000)] + ["m59999"]
    path.write_bytes(craft_zip([ZipMember.of(n, b"") for n in names]))
    outcome = shared_reader().run("project", path)
    check_bounded(outcome, path)
    assert "'m59999' appears twice" in outcome.message


# -- a theme folder whose list names a file with a NUL -------------------------
# Was: themes.json naming "a\u0000b.png" passed the "a file name in the folder" check
# and os.stat raised "ValueError: embedded null byte" (not the library's error, so a
# traceback for any caller). Now the name must be printable text, as models.json's.

@pytest.mark.parametrize("file", ["a\u0000b.png", "a\nb.png", "../grass.png", "/etc/passwd"])
def test_a_theme_file_name_that_is_no_plain_name_is_refused(tmp_path, file):
    (tmp_path / "themes.json").write_text(json.dumps(
        {"version": 1, "themes": [{"name": "g", "colour": [1, 2, 3], "file": file}]}))
    with pytest.raises(CorruptFileError, match="must be a file name in the theme folder"):
        read_theme_library(tmp_path)



@pytest.mark.parametrize("name", ["a\u0000b.ttproj", "../p.ttproj", "/tmp/p.ttproj"])
def test_an_export_naming_no_plain_project_file_is_one_line(export_folder, tmp_path, name):
    # A NUL in the manifest's "project" reached Path.resolve: "ValueError: embedded null
    # byte", a traceback (once the carried project is checked against the output).
    folder = tmp_path / "exp"
    folder.mkdir()
    manifest = json.loads((export_folder / "terratheme_unity.json").read_text())
    (folder / "terratheme_unity.json").write_text(json.dumps({**manifest, "project": name}))
    check_refused(run_cli("new", "--from", "export", folder, tmp_path / "back.ttproj"),
                  "'project' must be a file name beside the manifest")
