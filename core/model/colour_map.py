"""The colour map: a low-resolution colour gain laid over a thematic texture.

A class alone carries one texture and one colour; the colour map (a terrain engine's
*macro variation* map) keeps the photo's slow colour changes inside a class. Gain
``value / 128`` per channel, bilinear at ``(X + 0.5) / scale - 0.5`` in exact integers
(:mod:`core.render.colour_map`); layout, codecs and tiles: docs/formats.md, the colour map.
A map coded at an even scale may ship ``upsample = 2``: its decoded image is enlarged 2x
by bicubic interpolation and renders at half the coded scale (sharper than bilinear from
the coded pixels, for no bytes; docs/decisions.md). A coded map may also ship
``sharpen = q``: its drawn image then passes an exact unsharp mask of amount ``q / 4``
(:func:`sharpened`), which gives back the edges the block means and the codec soften.
A coded map may be *predicted*: its image holds the map less what the index grid predicts
(:mod:`core.model.map_prediction`), and ``pixels`` add the prediction back.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.codec import decode_image, encode_image

#: the stored value that leaves a texel unchanged
NEUTRAL = 128
#: largest texels per map pixel
MAX_SCALE = 4096
#: codec -> (largest side, most pixels) of a map shipped as one image: JPEG XL level 5
#: (ISO/IEC 18181-1 profile limits), WebP's 14-bit sizes, baseline JPEG's 16-bit ones,
#: libavif's default size limit
ONE_IMAGE_LIMITS = {
    "jpegxl": (1 << 18, 1 << 28),
    "webp": (16383, 16383 * 16383),
    "jpeg": (65535, 65535 * 65535),
    "png": ((1 << 31) - 1, 1 << 62),
    "avif": (16384, 16384 * 16384),
}
#: map pixels a side of the tiles of a map beyond its codec's single-image limit
MAP_TILE = 4096
#: the decoded image's enlargements a map may ship with (1: none)
UPSAMPLES = (1, 2)
#: the unsharp mask amounts (in quarters) a coded map may ship with (:func:`sharpened`)
SHARPENS = tuple(range(9))
#: rows of a drawn map :func:`sharpened` filters at a time (bounded memory on huge maps)
SHARPEN_ROWS = 1024

#: a map tile's place: ``(rows, cols)`` slices of the map
TileBox = tuple[slice, slice]


def _offset(image: np.ndarray, prediction: np.ndarray, sign: int) -> np.ndarray:
    """``clip(image + sign (prediction - 128), 0, 255)`` as uint8, ``SHARPEN_ROWS`` rows at
    a time (no whole-map int16 copy)."""
    if prediction.shape != image.shape:
        raise TerrathemeError(f"colour map prediction {prediction.shape[1]} x "
                              f"{prediction.shape[0]} for a {image.shape[1]} x "
                              f"{image.shape[0]} image")
    out = np.empty(image.shape, np.uint8)
    for r in range(0, image.shape[0], SHARPEN_ROWS):
        band = slice(r, r + SHARPEN_ROWS)
        offset = prediction[band].astype(np.int16) - NEUTRAL
        out[band] = np.clip(image[band] + sign * offset, 0, 255)
    return out


def residual(stored: np.ndarray, prediction: np.ndarray) -> np.ndarray:
    """``(mh, mw, 3)`` uint8 image a predicted map codes: ``stored - prediction + 128``."""
    return _offset(stored, prediction, -1)


def restored(decoded: np.ndarray, prediction: np.ndarray | None) -> np.ndarray:
    """``(mh, mw, 3)`` uint8 map of a decoded image: ``decoded + prediction - 128`` (the
    decoded image itself without a prediction)."""
    return decoded if prediction is None else _offset(decoded, prediction, 1)


@dataclass(frozen=True)
class TileEncoder:
    """One tile of a map beyond the single-image limit: its bytes and what they decode to.

    A picklable job (a worker process runs it as the client would); ``codec`` is a
    :mod:`core.io.codec` name.
    """

    codec: str
    quality: int

    def __call__(self, piece: np.ndarray) -> tuple[bytes, np.ndarray]:
        """``(bytes, (h, w, 3) uint8 decoded pixels)`` of an ``(h, w, 3)`` uint8 ``piece``."""
        data = encode_image(np.ascontiguousarray(piece), codec=self.codec, quality=self.quality)
        decoded = decode_image(data, codec=self.codec, shape=piece.shape[:2])
        return data, np.ascontiguousarray(decoded[:, :, :3])


#: ``run(encoder, boxes, piece, sink)``: ``sink(box, encoder(piece(box)))`` for every box, in
#: order (serially or in parallel; ``piece(box)`` is the map's pixels there)
TileRunner = Callable[[TileEncoder, list[TileBox], Callable[[TileBox], np.ndarray],
                       Callable[[TileBox, tuple[bytes, np.ndarray]], None]], object]


def tile_boxes(shape: tuple[int, int], tile: int) -> list[TileBox]:
    """The ``tile``-pixel tiles of an ``(mh, mw)`` map, row by row (the last ones smaller)."""
    mh, mw = int(shape[0]), int(shape[1])
    return [(slice(y, min(y + tile, mh)), slice(x, min(x + tile, mw)))
            for y in range(0, mh, tile) for x in range(0, mw, tile)]


def check_tile_members(shape: tuple[int, int], tile: object, names: object) -> None:
    """Refuse a tiled map's listing unless it is what :meth:`ColourMap.encode` writes:
    tiles of :data:`MAP_TILE`, one member of its own per tile, row by row (so work is
    bounded by the archive)."""
    rows, cols = ColourMap.tile_counts(shape, tile)
    if tile != MAP_TILE:
        raise TerrathemeError(f"colour map tiles of {tile} pixels: tiles are {MAP_TILE} "
                              "pixels a side")
    if (not isinstance(names, list) or len(names) != rows * cols
            or not all(isinstance(n, str) for n in names)):
        raise TerrathemeError(f"a {shape[1]} x {shape[0]} colour map in tiles of {tile} "
                              f"needs {rows * cols} tile members")
    if len(set(names)) != len(names):
        raise TerrathemeError("a colour map tile member is listed twice")


@dataclass(frozen=True, eq=False)
class ColourMap:
    """A per-channel colour gain over the texture (docs/formats.md, the colour map).

    ``pixels`` (mh, mw, 3) uint8: gain x 128 (read-only copy), as every renderer applies it;
    ``scale``: texels per map pixel, 1..4096; ``codec`` and ``data``: the map as it ships
    (:mod:`core.io.codec`), which ``pixels`` decode; ``tiles``: instead of ``data``,
    ``tile x tile`` pieces row by row. ``upsample``: the shipped image is at
    ``coded_scale = scale * upsample`` and ``pixels`` are its decode enlarged ``upsample``
    times and sharpened by ``sharpen`` quarters (:func:`drawn_pixels`), cut to the ``(W, H)``
    ``texture_size`` the constructors then need; they take the shipped image's scale.
    ``colours`` (K, 3) per theme and ``prediction`` (the ``coded_shape`` map they predict
    from the grid, uint8): a predicted map, whose image holds :func:`residual`.
    """

    pixels: np.ndarray
    scale: int
    codec: str | None = None
    data: bytes | None = None
    tiles: tuple[bytes, ...] | None = None
    tile: int | None = None
    upsample: int = 1
    sharpen: int = 0
    colours: tuple[tuple[int, int, int], ...] | None = None
    prediction: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        arr = np.asarray(self.pixels)
        if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
            raise TerrathemeError(f"colour map must be (h, w, 3), got shape {arr.shape}")
        if arr.dtype != np.uint8:
            raise TerrathemeError(f"colour map must be uint8, got {arr.dtype}")
        if isinstance(self.scale, bool) or not isinstance(self.scale, int | np.integer) or not (
                1 <= int(self.scale) <= MAX_SCALE):
            raise TerrathemeError(f"colour map scale must be an integer 1..{MAX_SCALE}, "
                                  f"got {self.scale!r}")
        check_upsample(self.upsample, coded=self.codec is not None)
        check_sharpen(self.sharpen, coded=self.codec is not None)
        frozen = np.array(arr, dtype=np.uint8, order="C")
        frozen.setflags(write=False)
        object.__setattr__(self, "pixels", frozen)
        object.__setattr__(self, "scale", int(self.scale))
        if self.tiles is not None:
            if self.data is not None or self.codec is None:
                raise TerrathemeError("a tiled colour map has a codec and no single image")
            rows, cols = self.tile_counts(self.coded_shape, self.tile)
            if len(self.tiles) != rows * cols:
                raise TerrathemeError(f"a {frozen.shape[1]} x {frozen.shape[0]} colour map in "
                                      f"tiles of {self.tile} has {rows * cols} tiles, "
                                      f"not {len(self.tiles)}")
            object.__setattr__(self, "tiles", tuple(bytes(t) for t in self.tiles))
        if (self.colours is None) != (self.prediction is None) or (
                self.colours is not None and (self.codec is None or self.tiles is not None)):
            raise TerrathemeError("a predicted colour map is coded in one image and has both "
                                  "its colours and its prediction")
        if self.colours is not None:
            object.__setattr__(self, "colours", _colour_rows(self.colours))
            prediction = np.array(self.prediction, dtype=np.uint8, order="C")
            if prediction.shape != (*self.coded_shape, 3):
                raise TerrathemeError("colour map prediction does not match its image")
            prediction.setflags(write=False)
            object.__setattr__(self, "prediction", prediction)

    @property
    def coded_scale(self) -> int:
        """Texels per pixel of the image as it ships."""
        return self.scale * self.upsample

    @property
    def coded_shape(self) -> tuple[int, int]:
        """``(mh, mw)`` of the image as it ships."""
        k = self.upsample
        return -(-self.pixels.shape[0] // k), -(-self.pixels.shape[1] // k)

    @classmethod
    def from_bytes(cls, data: bytes, codec: str, scale: int,
                   shape: tuple[int, int] | None = None, *, upsample: int = 1,
                   sharpen: int = 0, texture_size: tuple[int, int] | None = None,
                   colours: Sequence[Sequence[int]] | None = None,
                   prediction: np.ndarray | None = None) -> ColourMap:
        """The map shipped as ``data`` in ``codec`` at ``scale`` (``shape`` = expected
        ``(mh, mw)`` of that image), rendered ``upsample`` times finer, ``sharpen``ed;
        with ``colours`` and their ``prediction``, a predicted map."""
        drawn = _drawn_shape(scale, upsample, texture_size)
        check_sharpen(sharpen)
        pixels = decode_image(data, codec=codec, shape=shape)
        if pixels.shape[2] < 3:
            raise TerrathemeError(f"colour map must be RGB, the {codec} image has "
                                  f"{pixels.shape[2]} channel(s)")
        coded = restored(np.ascontiguousarray(pixels[:, :, :3]), prediction)
        return cls(drawn_pixels(coded, upsample, sharpen, drawn), scale // upsample,
                   codec, bytes(data), upsample=upsample, sharpen=sharpen, colours=colours,
                   prediction=prediction)

    @staticmethod
    def tile_counts(shape: tuple[int, int], tile: object) -> tuple[int, int]:
        """``(rows, cols)`` of ``tile``-pixel tiles over an ``(mh, mw)`` map."""
        if isinstance(tile, bool) or not isinstance(tile, int | np.integer) or int(tile) < 1:
            raise TerrathemeError(f"colour map tile must be a positive integer, got {tile!r}")
        return -(-int(shape[0]) // int(tile)), -(-int(shape[1]) // int(tile))

    @staticmethod
    def fits_one_image(shape: tuple[int, int], codec: str) -> bool:
        """Whether an ``(mh, mw)`` map ships as one ``codec`` image (:data:`ONE_IMAGE_LIMITS`)."""
        side, pixels = ONE_IMAGE_LIMITS.get(codec, ONE_IMAGE_LIMITS["png"])
        return max(shape) <= side and shape[0] * shape[1] <= pixels

    @classmethod
    def encode(cls, pixels: np.ndarray, scale: int, codec: str, quality: int, *,
               run: TileRunner | None = None, upsample: int = 1, sharpen: int = 0,
               texture_size: tuple[int, int] | None = None,
               colours: Sequence[Sequence[int]] | None = None,
               prediction: np.ndarray | None = None) -> ColourMap:
        """The map of stored gains ``pixels`` ``(mh, mw, 3) uint8`` at ``scale`` as it ships
        in ``codec``, rendered ``upsample`` times finer, ``sharpen``ed; with ``colours``
        and their ``prediction`` (``pixels``' shape), coded as their :func:`residual`
        (in one image only).

        One image when it fits the codec's single-image limit, else tiles of
        :data:`MAP_TILE`, each encoded by a :class:`TileEncoder`: one after the other
        here, or by ``run`` (e.g. in parallel; every runner gives the same map).
        """
        drawn = _drawn_shape(scale, upsample, texture_size)
        check_sharpen(sharpen)
        arr = np.ascontiguousarray(pixels)
        if prediction is not None:
            if not cls.fits_one_image(arr.shape[:2], codec):
                raise TerrathemeError("a predicted colour map ships in one image")
            arr = residual(arr, prediction)
        if cls.fits_one_image(arr.shape[:2], codec):
            return cls.from_bytes(encode_image(arr, codec=codec, quality=quality), codec, scale,
                                  upsample=upsample, sharpen=sharpen, texture_size=texture_size,
                                  colours=colours, prediction=prediction)
        t = MAP_TILE
        boxes = tile_boxes(arr.shape[:2], t)
        shown = np.empty_like(arr)
        tiles: list[bytes] = []

        def sink(box: TileBox, done: tuple[bytes, np.ndarray]) -> None:
            # What the tile decodes to is what renders (as from_tiles gives it on loading).
            tiles.append(done[0])
            shown[box] = done[1]

        encoder = TileEncoder(codec, int(quality))
        if run is None:
            for box in boxes:
                sink(box, encoder(arr[box]))
        else:
            run(encoder, boxes, arr.__getitem__, sink)
        if len(tiles) != len(boxes):
            raise TerrathemeError(f"{len(tiles)} of the colour map's {len(boxes)} tiles came "
                                  "back encoded")
        return cls(drawn_pixels(shown, upsample, sharpen, drawn), scale // upsample, codec,
                   None, tuple(tiles), t, upsample, sharpen)

    @classmethod
    def from_tiles(cls, tiles: Sequence[bytes], codec: str, scale: int,
                   shape: tuple[int, int], tile: int, *, upsample: int = 1, sharpen: int = 0,
                   texture_size: tuple[int, int] | None = None) -> ColourMap:
        """The map shipped as ``tile``-pixel tiles in ``codec``, row by row; ``shape`` ``(mh, mw)``
        and ``scale`` of the shipped image, rendered ``upsample`` times finer, ``sharpen``ed.

        Each tile's size is checked on its header before it is decoded.
        """
        drawn = _drawn_shape(scale, upsample, texture_size)
        check_sharpen(sharpen)
        rows, cols = cls.tile_counts(shape, tile)
        if len(tiles) != rows * cols:
            raise TerrathemeError(f"a {shape[1]} x {shape[0]} colour map in tiles of {tile} "
                                  f"has {rows * cols} tiles, not {len(tiles)}")
        mh, mw = int(shape[0]), int(shape[1])
        pixels = np.empty((mh, mw, 3), np.uint8)
        for k, data in enumerate(tiles):
            y, x = (k // cols) * tile, (k % cols) * tile
            want = (min(tile, mh - y), min(tile, mw - x))
            piece = decode_image(data, codec=codec, shape=want)
            if piece.shape[2] < 3:
                raise TerrathemeError(f"colour map must be RGB, tile {k} has "
                                      f"{piece.shape[2]} channel(s)")
            pixels[y:y + want[0], x:x + want[1]] = piece[:, :, :3]
        return cls(drawn_pixels(pixels, upsample, sharpen, drawn), scale // upsample, codec,
                   None, tuple(tiles), int(tile), upsample, sharpen)

    def redrawn(self, sharpen: int, texture_size: tuple[int, int]) -> ColourMap:
        """This shipped map (its bytes decoded again) drawn at another ``sharpen`` over a
        ``(W, H)`` ``texture_size`` texture."""
        if self.tiles is not None:
            return ColourMap.from_tiles(self.tiles, self.codec, self.coded_scale,
                                        self.coded_shape, self.tile, upsample=self.upsample,
                                        sharpen=sharpen, texture_size=texture_size)
        if self.data is None:
            raise TerrathemeError("a raw colour map has no shipped image to draw again")
        return ColourMap.from_bytes(self.data, self.codec, self.coded_scale,
                                    upsample=self.upsample, sharpen=sharpen,
                                    texture_size=texture_size, colours=self.colours,
                                    prediction=self.prediction)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ColourMap):
            return NotImplemented
        return self.scale == other.scale and np.array_equal(self.pixels, other.pixels)

    @staticmethod
    def shape_for(texture_size: tuple[int, int], scale: int) -> tuple[int, int]:
        """``(mh, mw)`` of the map covering a ``(W, H)`` texture at ``scale``."""
        w, h = texture_size
        return -(-h // scale), -(-w // scale)

    def check_covers(self, texture_size: tuple[int, int]) -> None:
        """Raise unless the map has exactly the shape for a ``(W, H)`` texture."""
        want = self.shape_for(texture_size, self.scale)
        if self.pixels.shape[:2] != want:
            raise TerrathemeError(
                f"colour map is {self.pixels.shape[1]} x {self.pixels.shape[0]} at scale "
                f"{self.scale}, but a {texture_size[0]} x {texture_size[1]} texture needs "
                f"{want[1]} x {want[0]}"
            )

    @property
    def nbytes(self) -> int:
        """Bytes as shipped (``data`` or ``tiles``), else of the raw pixels."""
        if self.tiles is not None:
            return sum(len(t) for t in self.tiles)
        return len(self.data) if self.data is not None else int(self.pixels.nbytes)


def _colour_rows(colours: Sequence[Sequence[int]] | None
                 ) -> tuple[tuple[int, int, int], ...] | None:
    """A predicted map's theme colours as ``(r, g, b)`` tuples (None: not predicted)."""
    if colours is None:
        return None
    return tuple((int(r), int(g), int(b)) for r, g, b in np.asarray(colours).tolist())


def check_upsample(upsample: object, *, scale: int | None = None, coded: bool = True) -> None:
    """Raise unless ``upsample`` is one of :data:`UPSAMPLES`, divides the shipped image's
    ``scale`` (when given) and is above 1 only for a ``coded`` map."""
    if (isinstance(upsample, bool) or upsample not in UPSAMPLES
            or (scale is not None and int(scale) % upsample) or (upsample > 1 and not coded)):
        at = "" if scale is None else f" at scale {scale}"
        raise TerrathemeError(f"colour map upsample must be one of {UPSAMPLES}, dividing the "
                              f"scale (above 1 only for a coded map), got {upsample!r}{at}")


def check_sharpen(sharpen: object, *, coded: bool = True) -> None:
    """Raise unless ``sharpen`` is one of :data:`SHARPENS`, above 0 only for a ``coded`` map."""
    if (isinstance(sharpen, bool) or not isinstance(sharpen, int | np.integer)
            or sharpen not in SHARPENS or (sharpen and not coded)):
        raise TerrathemeError(f"colour map sharpen must be an integer {SHARPENS[0]}.."
                              f"{SHARPENS[-1]} (above 0 only for a coded map), got {sharpen!r}")


def _drawn_shape(scale: int, upsample: int, texture_size: tuple[int, int] | None
                 ) -> tuple[int, int] | None:
    """``(mh, mw)`` of the drawn map of a ``texture_size`` texture (None: no upsampling)."""
    check_upsample(upsample, scale=scale)
    if upsample == 1:
        return None
    if texture_size is None:
        raise TerrathemeError("an upsampled colour map needs the size of its texture")
    return ColourMap.shape_for(texture_size, int(scale) // upsample)


def drawn_pixels(pixels: np.ndarray, upsample: int, sharpen: int = 0,
                 shape: tuple[int, int] | None = None) -> np.ndarray:
    """``(mh, mw, 3)`` uint8 decoded map pixels as they render: enlarged ``upsample`` times,
    :func:`sharpened` by ``sharpen`` quarters, cut to ``shape`` (at most ``(k*mh, k*mw)``;
    None: all of it).

    OpenCV's bicubic (a = -0.75, edge pixels replicated, 8-bit fixed point): new pixel ``j``
    sits at ``(j + 0.5) / k - 0.5`` of the old ones, the place of its texels' centre.
    """
    h, w = pixels.shape[:2]
    big = pixels if upsample == 1 else cv2.resize(
        np.ascontiguousarray(pixels), (w * upsample, h * upsample), interpolation=cv2.INTER_CUBIC)
    big = sharpened(big, sharpen)
    if shape is None:
        return big
    if shape[0] > big.shape[0] or shape[1] > big.shape[1]:
        raise TerrathemeError(f"a {w} x {h} colour map enlarged {upsample}x cannot cover "
                              f"{shape[1]} x {shape[0]} pixels")
    return np.ascontiguousarray(big[:shape[0], :shape[1]])


#: the unsharp mask's blur: the binomial [1 4 6 4 1] / 16 on both axes (Gaussian sigma 1)
_BINOMIAL = np.array([1, 4, 6, 4, 1], np.float32)


def sharpened(pixels: np.ndarray, sharpen: int) -> np.ndarray:
    """(h, w, 3) uint8: ``p + (sharpen / 4) (p - B p)``, rounded half up and clipped to 0..255,
    with ``B`` the 5-tap binomial blur (edge pixels replicated).

    Exact: ``B p`` times 256 is an integer under 2^24, which float32 holds, so every machine
    draws the same map. ``sharpen`` 0 returns ``pixels``.
    """
    if not sharpen:
        return pixels
    h = pixels.shape[0]
    out = np.empty_like(pixels)
    for y0 in range(0, h, SHARPEN_ROWS):
        # Rows y0 .. y1 with two rows of context each side (the blur's reach).
        y1 = min(h, y0 + SHARPEN_ROWS)
        a, b = max(0, y0 - 2), min(h, y1 + 2)
        p = pixels[a:b].astype(np.float32)
        blur = cv2.sepFilter2D(p, cv2.CV_32F, _BINOMIAL, _BINOMIAL,
                               borderType=cv2.BORDER_REPLICATE)
        value = np.floor((1024.0 * p + sharpen * (256.0 * p - blur) + 512.0) / 1024.0)
        out[y0:y1] = np.clip(value, 0, 255)[y0 - a:y0 - a + (y1 - y0)].astype(np.uint8)
    return out
