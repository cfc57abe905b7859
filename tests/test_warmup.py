"""``python -m terratheme.app.warmup`` compiles what a conversion runs: no compile on first run.

A numba kernel is compiled once per argument types (layout included: a view is
'A', a whole array 'C'); a type the warmup does not give it is compiled at the
user's first run (seconds). These tests run the warmup's part, then a
conversion of a photo larger than a classification tile, and look for new
signatures.
"""

from __future__ import annotations

import sys

import numpy as np
from numba.core.registry import CPUDispatcher
from terratheme.app import warmup
from terratheme.core.classify import classify_unsupervised
from terratheme.core.classify.tiled import _arg_max
from terratheme.core.convert.photo import convert_photo


def _signatures() -> set[tuple[str, str]]:
    """(kernel, signature) of every numba kernel of core compiled in this process."""
    out = set()
    for name, module in list(sys.modules.items()):
        if name.startswith("terratheme.core."):
            for attr, value in vars(module).items():
                if isinstance(value, CPUDispatcher) and value.__module__ == name:
                    out.update((f"{name}.{attr}", str(s)) for s in value.signatures)
    return out


def _photo(h: int, w: int) -> np.ndarray:
    """Three regions of noisy colour (sand, dark, blue)."""
    rng = np.random.default_rng(5)
    photo = rng.integers(0, 40, (h, w, 3), dtype=np.uint8)
    photo[:, w // 3 :] += np.array([150, 120, 40], np.uint8)
    photo[h // 2 :, 2 * w // 3 :] = rng.integers(20, 60, (h - h // 2, w - 2 * w // 3, 3),
                                                 dtype=np.uint8) + np.array([0, 60, 160],
                                                                            np.uint8)
    return photo


def test_arg_max_has_one_signature_for_one_tile_and_many():
    # A photo within one 1024 px tile and one of two tiles (its tiles are views of the
    # labels: the kernel must not see them as such).
    classify_unsupervised(_photo(96, 128))
    classify_unsupervised(_photo(64, 1100))
    assert len(_arg_max.signatures) == 1


def test_convert_after_the_warmup_compiles_nothing_new():
    warmup.main(["convert"])
    before = _signatures()
    convert_photo(_photo(200, 1100))
    assert sorted(_signatures() - before) == []


def test_a_region_narrower_than_the_grid_renders_with_the_whole_grid_s_signatures():
    # A viewport's block of the grid is a strided view: passed as it is, each rows kernel
    # compiled a second ('A') signature at the first viewport render after the warmup.
    from terratheme.core.render import BlendMode, RenderOptions, render_cells, render_labels
    from terratheme.core.render import kernels as rk
    from terratheme.core.render.boundary import BoundaryOptions, shaped_rows

    grid = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 1]], np.uint8)
    themes = [np.full((8, 8, 3), 40 * (k + 1), np.uint8) for k in range(2)]
    for options in (RenderOptions(blend=BlendMode.LINEAR), RenderOptions(
            blend=BlendMode.HISTOGRAM), RenderOptions(boundary=BoundaryOptions())):
        whole = render_cells(grid, themes, (4, 4), options=options)
        np.testing.assert_array_equal(render_cells(grid, themes, (4, 4), (1, 1, 3, 6),
                                                   options=options), whole[1:7, 1:4])
    labels = render_labels(grid, (4, 4))
    np.testing.assert_array_equal(render_labels(grid, (4, 4), (5, 0, 2, 8)), labels[:, 5:7])
    for kernel in (rk.linear_rows, rk.histogram_rows, rk.label_rows, shaped_rows):
        assert {sig[3][0].layout for sig in kernel.signatures} == {"C"}, kernel


def test_kernel_hash_follows_numba_sources_only(tmp_path):
    (tmp_path / "k.py").write_text("import numba\n")
    (tmp_path / "plain.py").write_text("x = 1\n")
    first = warmup.kernel_sources_hash(tmp_path)
    (tmp_path / "plain.py").write_text("x = 2\n")
    assert warmup.kernel_sources_hash(tmp_path) == first
    (tmp_path / "k.py").write_text("import numba  # edited\n")
    assert warmup.kernel_sources_hash(tmp_path) != first


def test_if_changed_compiles_only_what_the_stamp_lacks(tmp_path, monkeypatch, capsys):
    ran = []
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(warmup, "PARTS", {n: (lambda n=n: ran.append(n)) for n in "abc"})
    monkeypatch.setattr(warmup, "DEFAULT_GROUPS", (("a", "b"),))
    digest = ["one"]
    monkeypatch.setattr(warmup, "kernel_sources_hash", lambda root=None: digest[0])
    assert warmup.main(["--if-changed"]) == 0 and ran == ["a", "b"]
    assert warmup.main(["--if-changed"]) == 0 and ran == ["a", "b"]
    assert "up to date" in capsys.readouterr().out
    assert warmup.main(["--if-changed", "c"]) == 0 and ran == ["a", "b", "c"]
    assert warmup.main(["--if-changed", "a", "c"]) == 0 and ran == ["a", "b", "c"]
    digest[0] = "two"  # a kernel source changed: everything again
    assert warmup.main(["--if-changed"]) == 0 and ran == ["a", "b", "c", "a", "b"]
    assert warmup.main(["nope"]) == 2
