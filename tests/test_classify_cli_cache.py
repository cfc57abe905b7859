"""``terratheme classify --cache-dir``: a second training on the same pairs is the cached model."""

from __future__ import annotations

import re

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import read_labels, write_image


@pytest.fixture()
def files(tmp_path):
    rng = np.random.default_rng(0)
    truth = np.kron(rng.integers(0, 2, (4, 6)), np.ones((16, 16), np.uint8)) * 5 + 2
    colours = np.array([[0, 0, 0]] * 2 + [[40, 120, 40]] + [[0, 0, 0]] * 4 + [[190, 170, 140]])
    photo = np.clip(colours[truth] + rng.normal(0, 10, truth.shape + (3,)), 0, 255)
    write_image(tmp_path / "photo.png", photo.astype(np.uint8))
    write_image(tmp_path / "truth.png", truth.astype(np.uint8))
    return tmp_path, truth


def _classify(d, out, *extra):
    return main(["classify", str(d / "photo.png"), "-o", str(d / out),
                 "--train", str(d / "photo.png"), str(d / "truth.png"), *extra])


def test_the_second_run_takes_the_model_from_the_cache(files, capsys):
    d, truth = files
    cache = d / "cache"
    assert _classify(d, "plain.png") == 0
    assert _classify(d, "first.png", "--cache-dir", str(cache)) == 0
    assert "model from the cache" not in capsys.readouterr().out
    assert sorted(p.suffix for p in cache.iterdir()) == [".model", ".samples"]
    assert _classify(d, "second.png", "--cache-dir", str(cache), "--legend",
                     str(_legend(d))) == 0
    out = capsys.readouterr().out
    assert f"model from the cache {cache}" in out and "2 grass" in out
    first, second = read_labels(d / "first.png"), read_labels(d / "second.png")
    np.testing.assert_array_equal(second, first)
    assert (first == truth).mean() > 0.95
    assert (read_labels(d / "plain.png") == first).mean() > 0.999


def _legend(d):
    (d / "legend.json").write_text('{"2": "grass", "7": "sand"}')
    return d / "legend.json"


@pytest.mark.parametrize(("extra", "match"), [
    (["--train", "{d}/photo.png", "{d}/truth.png", "--cache-dir", "{d}/blocker/cache"],
     "--cache-dir {d}/blocker/cache: cannot use the folder"),
    (["--cache-dir", "{d}/cache"], "--cache-dir keeps training samples and models: it needs "
                                   "--scribbles or --train"),
    (["--train", "{d}/photo.png", "{d}/truth.png", "--cache-size", "2G"],
     "--cache-size bounds the --cache-dir folder: give --cache-dir too"),
])
def test_a_bad_cache_folder_is_one_line_before_any_work(files, capsys, extra, match):
    d, _ = files
    (d / "blocker").write_bytes(b"x")
    args = ["classify", str(d / "photo.png"), "-o", str(d / "l.png"),
            *(a.format(d=d) for a in extra)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match.format(d=d) in err[0]
    assert not (d / "l.png").exists() and not (d / "cache").exists()
    from terratheme.app.cli import build_parser
    from terratheme.app.commands import classify

    with pytest.raises(TerrathemeError, match=re.escape(match.format(d=d))):
        classify.run(build_parser().parse_args(args))


NINES = "9" * 400


@pytest.mark.parametrize(("size", "match"), [
    ("2X", "--cache-size must be a number of bytes with an optional unit K, M, G or T "
           "(e.g. 2G, 500M), not '2X'"),
    ("0M", "--cache-size must be from one byte to 1024T, not '0M'"),
    ("1025T", "--cache-size must be from one byte to 1024T, not '1025T'"),
    (NINES, f"--cache-size must be from one byte to 1024T, not '{NINES}'"),   # was OverflowError
    (NINES + "." + NINES, "--cache-size must be from one byte to 1024T"),
])
def test_a_bad_cache_size_is_one_line(files, capsys, size, match):
    d, _ = files
    with pytest.raises(SystemExit) as exit_:
        main(["classify", str(d / "photo.png"), "-o", str(d / "l.png"), "--train",
              str(d / "photo.png"), str(d / "truth.png"), "--cache-dir", str(d / "cache"),
              "--cache-size", size])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2 and len(err) == 1 and match in err[0]
    assert not (d / "l.png").exists() and not (d / "cache").exists()


@pytest.mark.parametrize(("size", "expected"), [
    ("2G", 2_147_483_648), ("500M", 524_288_000), ("1.5g", 1_610_612_736), ("4096", 4096),
    ("64KiB", 65_536), (" 3 T ", 3_298_534_883_328), ("10mb", 10_485_760), (".5K", 512),
    ("1024T", 1 << 50),
])
def test_sizes_are_read_in_binary_units(size, expected):
    from terratheme.app.commands.classify import _cache_size

    assert _cache_size(size) == expected


def test_the_cache_size_bounds_the_folder(files, capsys):
    d, _ = files
    cache = d / "cache"
    # The pair's samples (about 16.4 KB) and then the model (about 3.5 KB) do not fit
    # 19 KiB together: the samples, used least recently, go.
    assert _classify(d, "first.png", "--cache-dir", str(cache), "--cache-size", "19K") == 0
    kept = list(cache.iterdir())
    assert [p.suffix for p in kept] == [".model"]
    assert kept[0].stat().st_size <= 19 * 1024
    capsys.readouterr()
    assert _classify(d, "second.png", "--cache-dir", str(cache), "--cache-size", "19K") == 0
    assert f"model from the cache {cache}" in capsys.readouterr().out
    assert sum(p.stat().st_size for p in cache.iterdir()) <= 19 * 1024
    np.testing.assert_array_equal(read_labels(d / "second.png"), read_labels(d / "first.png"))


def test_the_help_names_the_default_bound(capsys):
    from terratheme.app.commands.classify import _cache_size
    from terratheme.core.io.disk_cache import DEFAULT_CACHE_BYTES

    with pytest.raises(SystemExit):
        main(["classify", "-h"])
    help_text = " ".join(capsys.readouterr().out.split())
    default = re.search(r"--cache-size SIZE bound [^)]*default (\w+)\)", help_text).group(1)
    assert _cache_size(default) == DEFAULT_CACHE_BYTES
