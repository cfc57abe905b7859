"""Theme and grid data as OpenGL textures (the layouts ``shaders/tt_blend.glsl`` documents).

The exact path reads themes of any sizes from one padded array with ``texelFetch``;
the filtered path resamples them to one size (``REPEAT``, mipmaps); flat renders below
scale 1 read each theme's summed-area table at its own size (box means over any
axis-aligned footprint); the histogram-preserving blend's Gaussianised themes and
inverse tables are the CPU's own.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import moderngl
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.render.theme_pack import LUT_RANGE, pack_themes


def _rgba(rgb: np.ndarray) -> np.ndarray:
    """An opaque RGBA copy of a ``(h, w, 3)`` uint8 image (the layout GL reads fastest)."""
    return np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=2)


def _resample_wrapped(tex: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``tex`` resampled to ``size = (w, h)`` as a periodic image (no seam where it wraps)."""
    h, w = tex.shape[:2]
    if (w, h) == size:
        return tex
    big = np.tile(tex, (3, 3, 1))
    shrink = size[0] < w or size[1] < h
    out = cv2.resize(big, (3 * size[0], 3 * size[1]),
                     interpolation=cv2.INTER_AREA if shrink else cv2.INTER_CUBIC)
    return out[size[1] : 2 * size[1], size[0] : 2 * size[0]]


def _stack(layers: Sequence[np.ndarray], size: tuple[int, int], fill: float) -> np.ndarray:
    """Layers padded to ``size = (w, h)`` (bottom-right), as one ``(K, h, w, c)`` array."""
    w, h = size
    c = layers[0].shape[2]
    out = np.full((len(layers), h, w, c), fill, dtype=layers[0].dtype)
    for k, layer in enumerate(layers):
        out[k, : layer.shape[0], : layer.shape[1]] = layer
    return out


def summed_area(texture: np.ndarray) -> np.ndarray:
    """(2h+1, 2w+1, 3) uint32 sums above-left of each corner of an (h, w, 3) theme tiled
    2 x 2: a box of at most one period is four reads (modulo 2^32: sums < 2^31 exact)."""
    tiled = np.tile(np.asarray(texture, np.uint64), (2, 2, 1))
    out = np.zeros((tiled.shape[0] + 1, tiled.shape[1] + 1, 3), np.uint64)
    out[1:, 1:] = tiled.cumsum(axis=0).cumsum(axis=1)
    return (out & 0xFFFFFFFF).astype(np.uint32)


class ThemeTextures:
    """The themes of one renderer on the GPU, uploaded once, each layout made when first
    needed; TerrathemeError for more themes than layers or a theme beyond the largest texture.
    """

    def __init__(self, ctx: moderngl.Context, textures: Sequence[np.ndarray]) -> None:
        self.ctx = ctx
        self.textures = list(textures)
        self.max_size = max_size = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        max_layers = int(ctx.info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
        if len(self.textures) > max_layers:
            raise TerrathemeError(f"{len(self.textures)} themes: this OpenGL driver holds at "
                                  f"most {max_layers} texture layers")
        for k, t in enumerate(self.textures):
            if max(t.shape[:2]) > max_size:
                raise TerrathemeError(f"theme {k} is {t.shape[1]} x {t.shape[0]}: this OpenGL "
                                      f"driver's textures are at most {max_size} texels wide")
        #: (K, 4) float32: w, h, 1/w, 1/h of every theme
        self.sizes = np.array([(t.shape[1], t.shape[0], 1.0 / t.shape[1], 1.0 / t.shape[0])
                               for t in self.textures], dtype=np.float32)
        #: the layer size (w, h): the largest theme's
        self.layer_size = (max(t.shape[1] for t in self.textures),
                           max(t.shape[0] for t in self.textures))
        #: every theme has the layer size (the exact path may wrap with REPEAT)
        self.one_size = all(t.shape[:2] == self.layer_size[::-1] for t in self.textures)
        self._made: dict[tuple, moderngl.Texture | moderngl.TextureArray] = {}

    def _array(self, layers: Sequence[np.ndarray], dtype: str, filtered: bool,
               anisotropy: float) -> moderngl.TextureArray:
        w, h = self.layer_size
        if filtered:
            layers = [_resample_wrapped(t, (w, h)) for t in layers]
        data = _stack(layers, (w, h), 255 if dtype == "f1" else 0.0)
        tex = self.ctx.texture_array((w, h, len(layers)), data.shape[3],
                                     np.ascontiguousarray(data).tobytes(), dtype=dtype)
        if filtered:
            tex.repeat_x = tex.repeat_y = True
            tex.build_mipmaps()
            tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            tex.anisotropy = min(float(anisotropy), float(self.ctx.max_anisotropy))
        else:
            # REPEAT serves themes of the layer size (TT_ONE_SIZE); texelFetch ignores it.
            tex.repeat_x = tex.repeat_y = True
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return tex

    def _cached(self, key: tuple, make):
        if key not in self._made:
            self._made[key] = make()
        return self._made[key]

    def colours(self, filtered: bool, anisotropy: float = 16.0) -> moderngl.TextureArray:
        """The RGBA8 theme array (``tt_themes``) of the exact or the filtered path."""
        def make():
            return self._array([_rgba(t) for t in self.textures], "f1", filtered, anisotropy)

        return self._cached(("colours", filtered, anisotropy if filtered else 0.0), make)

    def box_sums(self) -> moderngl.TextureArray:
        """The RGB32UI summed-area tables of the themes (``tt_box``), made once.

        Layer k: :func:`summed_area` of theme k at its own size, padded; read with
        ``texelFetch`` (``tt_box_mean`` in ``shaders/tt_filtered.glsl``).
        """
        def make():
            w, h = 2 * self.layer_size[0] + 1, 2 * self.layer_size[1] + 1
            area = max((t.shape[0] + 1) * (t.shape[1] + 1) for t in self.textures)
            if max(w, h) > self.max_size or 255 * area >= 2**31:
                raise TerrathemeError(f"a {w} x {h} summed-area table of the themes is beyond "
                                      f"this driver's {self.max_size} texels or 2^31 per box: "
                                      "render at scale 1 or on the CPU")
            data = _stack([summed_area(t) for t in self.textures], (w, h), 0)
            tex = self.ctx.texture_array((w, h, len(self.textures)), 3,
                                         np.ascontiguousarray(data).tobytes(), dtype="u4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            return tex

        return self._cached(("box",), make)

    def _gaussian_pack(self):
        return pack_themes(self.textures, 1, gaussian=True)

    def gaussianised(self, filtered: bool, anisotropy: float = 16.0) -> moderngl.TextureArray:
        """The RGB32F Gaussianised themes (``tt_gauss``), from the CPU renderer's pack."""
        def make():
            packed = self._gaussian_pack()
            # The pack pre-tiles rows by one column (cell width 1): cut it back off.
            layers = [packed.gflat[o : o + h * s].reshape(h, w + 1, 3)[:, :w]
                      for o, s, h, w in zip(packed.off, packed.stride, packed.th, packed.tw,
                                            strict=True)]
            return self._array([np.ascontiguousarray(g, np.float32) for g in layers], "f4",
                               filtered, anisotropy)

        return self._cached(("gauss", filtered, anisotropy if filtered else 0.0), make)

    def inverse_lut(self) -> tuple[moderngl.Texture, int, float]:
        """``(tt_inverse_lut, LUT entries, LUT half-range)``: R32F, row ``3k + c``."""
        def make():
            lut = np.ascontiguousarray(self._gaussian_pack().inv_lut, dtype=np.float32)
            if max(lut.shape) > self.max_size:
                raise TerrathemeError(f"the histogram blend's {lut.shape[1]} x {lut.shape[0]} "
                                      f"inverse table exceeds this driver's {self.max_size} "
                                      "texture size")
            tex = self.ctx.texture((lut.shape[1], lut.shape[0]), 1, lut.tobytes(), dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            return tex

        tex = self._cached(("lut",), make)
        return tex, tex.width, LUT_RANGE

    def release(self) -> None:
        """Free the GPU memory of every layout made."""
        for tex in self._made.values():
            tex.release()
        self._made.clear()


#: largest colour map scale the exact path divides exactly (512 s^2 <= 2^30, tt_colour.glsl)
MAX_COLOUR_SCALE = 1448


def check_colour_map(colour_map: ColourMap | None, texture_size: tuple[int, int]) -> None:
    """Refuse a colour map not covering a ``(W, H)`` texture or beyond :data:`MAX_COLOUR_SCALE`."""
    if colour_map is None:
        return
    if not isinstance(colour_map, ColourMap):
        raise TerrathemeError(f"colour map must be a ColourMap (pixels and scale), got "
                              f"{type(colour_map).__name__}")
    colour_map.check_covers(texture_size)
    if colour_map.scale > MAX_COLOUR_SCALE:
        raise TerrathemeError(f"colour map scale {colour_map.scale} is beyond the GPU "
                              f"renderer's exact range (up to {MAX_COLOUR_SCALE} texels per "
                              "map pixel): render it on the CPU")


def colour_map_texture(ctx: moderngl.Context, colour_map: ColourMap) -> moderngl.Texture:
    """The colour map as a clamped, mipmapped RGBA8 texture (level 0 for the exact path)."""
    arr = colour_map.pixels
    tex = ctx.texture((arr.shape[1], arr.shape[0]), 4, _rgba(arr).tobytes())
    tex.repeat_x = tex.repeat_y = False
    tex.build_mipmaps()
    tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    return tex
