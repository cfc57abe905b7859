"""Image file round trips through OpenImageIO and the atomic writer."""

from pathlib import Path

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.atomic import atomic_path, write_bytes_atomic
from terratheme.core.io.images import (
    image_info,
    read_image,
    read_region,
    read_windows,
    write_image,
)


@pytest.mark.parametrize("shape", [(8, 8), (4, 6), (6, 4), (1, 1), (1, 9), (9, 1)])
def test_png_round_trip_of_2d_arrays_is_not_transposed(tmp_path, shape):
    # DESIGN.md §5: OIIO misreads 2-D arrays; write_image must pass (H, W, 1).
    img = np.arange(np.prod(shape), dtype=np.uint8).reshape(shape) * 3
    write_image(tmp_path / "a.png", img)
    back = read_image(tmp_path / "a.png")
    assert back.shape == shape + (1,)
    np.testing.assert_array_equal(back[..., 0], img)


@pytest.mark.parametrize(
    ("suffix", "dtype"),
    [(".png", np.uint8), (".png", np.uint16), (".tif", np.uint16), (".tif", np.uint8),
     (".exr", np.float32)],
)
def test_rgb_round_trip_keeps_values_and_dtype(tmp_path, suffix, dtype):
    rng = np.random.default_rng(1)
    if dtype == np.float32:
        img = rng.random((5, 7, 3), dtype=np.float32)
    else:
        img = rng.integers(0, np.iinfo(dtype).max, (5, 7, 3), endpoint=True).astype(dtype)
    write_image(tmp_path / f"a{suffix}", img)
    back = read_image(tmp_path / f"a{suffix}")
    assert back.dtype == dtype
    np.testing.assert_array_equal(back, img)


def test_read_with_dtype_rescales_16_bit_to_8_bit(tmp_path):
    img = np.array([[[0, 65535, 32896]]], dtype=np.uint16)
    write_image(tmp_path / "a.tif", img)
    np.testing.assert_array_equal(read_image(tmp_path / "a.tif", dtype=np.uint8), [[[0, 255, 128]]])


def test_gif_reads_as_colour_plus_its_alpha(tmp_path):
    # OpenImageIO's GIF reader marks alpha as channel 4 of R, G, B, A: the A channel is used.
    rgb = np.random.default_rng(0).integers(0, 256, (6, 8, 3), dtype=np.uint8)
    write_image(tmp_path / "a.gif", rgb)
    assert image_info(tmp_path / "a.gif").alpha_channel == 3
    back = read_image(tmp_path / "a.gif")
    assert back.shape == (6, 8, 4)
    np.testing.assert_array_equal(back[..., :3], rgb)
    assert (back[..., 3] == 255).all()


@pytest.mark.parametrize("tile", [None, 16])
def test_read_region_equals_crop_of_whole_image(tmp_path, tile):
    rng = np.random.default_rng(2)
    img = rng.integers(0, 255, (50, 70, 3), dtype=np.uint8)
    write_image(tmp_path / "a.tif", img, tile=tile)
    info = image_info(tmp_path / "a.tif")
    assert (info.width, info.height, info.channels, info.tiled) == (70, 50, 3, tile is not None)
    for x, y, w, h in [(0, 0, 70, 50), (13, 5, 20, 33), (69, 49, 1, 1), (16, 16, 16, 16)]:
        np.testing.assert_array_equal(read_region(tmp_path / "a.tif", x, y, w, h),
                                      img[y : y + h, x : x + w])


@pytest.mark.parametrize(("name", "tile"), [("a.jpg", None), ("a.png", None), ("a.tif", None),
                                           ("t.tif", 16)])
def test_read_windows_are_the_whole_images_crops_in_any_order(tmp_path, monkeypatch, name, tile):
    import terratheme.core.io.images as images

    rng = np.random.default_rng(4)
    write_image(tmp_path / name, rng.integers(0, 255, (90, 70, 3), dtype=np.uint8), tile=tile)
    whole = read_image(tmp_path / name)
    opened = []
    real_open = images._open_input
    monkeypatch.setattr(images, "_open_input", lambda p: opened.append(p) or real_open(p))
    # Top rows in order (a row of tiles, then the next, overlapping), then two going up.
    boxes = [(0, 0, 30, 40), (25, 0, 45, 40), (0, 30, 70, 20), (10, 35, 5, 55), (3, 89, 1, 1),
             (0, 10, 70, 30), (69, 0, 1, 90)]
    for (x, y, w, h), got in zip(boxes, read_windows(tmp_path / name, boxes), strict=True):
        np.testing.assert_array_equal(got, whole[y:y + h, x:x + w])
        got[...] = 0  # a window is its own array, never a view of rows kept for the next
    # One opening, and one more for each window above the rows a scanline file kept.
    assert len(opened) == (1 if tile else 3)


def test_read_region_outside_image_is_an_error(tmp_path):
    write_image(tmp_path / "a.png", np.zeros((4, 4), np.uint8))
    with pytest.raises(TerrathemeError, match="outside the 4 x 4 image"):
        read_region(tmp_path / "a.png", 2, 2, 3, 1)


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(TerrathemeError, match="no such file"):
        read_image(tmp_path / "nope.png")


def test_folder_is_not_an_image(tmp_path):
    with pytest.raises(TerrathemeError, match="is a folder"):
        read_image(tmp_path)


def test_garbage_file_is_a_corrupt_file_error(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"this is not a png at all")
    with pytest.raises(CorruptFileError, match="bad.png"):
        read_image(tmp_path / "bad.png")


def test_truncated_png_is_a_corrupt_file_error(tmp_path):
    rng = np.random.default_rng(3)
    write_image(tmp_path / "a.png", rng.integers(0, 255, (64, 64, 3), dtype=np.uint8))
    data = (tmp_path / "a.png").read_bytes()
    (tmp_path / "t.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(CorruptFileError, match="t.png"):
        read_image(tmp_path / "t.png")


@pytest.mark.parametrize("shape", [(0, 5), (5, 0), (0, 0, 3), (3, 3, 0)])
def test_writing_an_empty_image_is_refused_and_leaves_no_file(tmp_path, shape):
    with pytest.raises(TerrathemeError, match="no pixels"):
        write_image(tmp_path / "e.png", np.zeros(shape, np.uint8))
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_no_file_and_keeps_the_old_one(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("disk full")
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_write_bytes_atomic_into_missing_folder_is_a_clear_error(tmp_path):
    with pytest.raises(TerrathemeError, match="does not exist"):
        write_bytes_atomic(tmp_path / "no" / "x.bin", b"1")
    write_bytes_atomic(tmp_path / "x.bin", b"1")
    assert Path(tmp_path / "x.bin").read_bytes() == b"1"


def test_atomic_output_gets_ordinary_permissions(tmp_path):
    import os

    umask = os.umask(0o022)
    try:
        write_bytes_atomic(tmp_path / "x.bin", b"1")
    finally:
        os.umask(umask)
    assert (tmp_path / "x.bin").stat().st_mode & 0o777 == 0o644
