"""Options of the GPU renderer: the sampling path and the rest (docs/gpu.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from terratheme.core.errors import TerrathemeError
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.renderer import BlendMode, RenderOptions
from terratheme.core.render.rules import SaddleRule

#: the CPU preview's sky colour (core.perspective.FilterOptions' default)
SKY = (0.62, 0.74, 0.88)


class Sampling(Enum):
    """How the shaders read the themes."""

    #: exact at scale 1, filtered below
    AUTO = "auto"
    #: texelFetch with integer wrap: the CPU render's texels (scale 1 only)
    EXACT = "exact"
    #: any scale: each theme's mean over the pixel (the fly-over: mipmaps, anisotropic)
    FILTERED = "filtered"


@dataclass(frozen=True)
class GpuRenderOptions:
    """Options of :meth:`GpuRenderer.render`.

    Attributes
    ----------
    max_anisotropy : float
        Anisotropic filtering limit of the filtered path: 1 for flat renders (isotropic
        footprints; llvmpipe blurs them with it on), 16 for grazing fly-overs.
    tile : int
        Largest framebuffer side; bigger outputs are rendered tile by tile.
    boundary : BoundaryOptions or None
        Borders shaped by the themes (linear blend only); None: the paper's ramp.
    max_supersample : int
        Filtered path: most weight sub-samples per pixel side (two per cell spanned), 1..64.
    """

    blend: BlendMode = BlendMode.LINEAR
    saddle: SaddleRule = SaddleRule.MINORITY
    sampling: Sampling = Sampling.AUTO
    max_anisotropy: float = 1.0
    tile: int = 4096
    boundary: BoundaryOptions | None = None
    max_supersample: int = 16

    def __post_init__(self) -> None:
        if self.boundary is not None and self.blend is not BlendMode.LINEAR:
            raise TerrathemeError("shaped boundaries blend linearly: use BlendMode.LINEAR "
                                  "with a boundary, or no boundary with the histogram blend")
        if not 1 <= int(self.max_supersample) <= 64:
            raise TerrathemeError(f"max_supersample must be 1..64, got {self.max_supersample}")

    @classmethod
    def from_render_options(cls, style: RenderOptions, **kwargs) -> GpuRenderOptions:
        """The GPU options drawing what ``style`` draws on the CPU (blend, saddle, borders)."""
        return cls(blend=style.blend, saddle=style.saddle, boundary=style.boundary, **kwargs)


class Anisotropy(Enum):
    """Who filters the themes anisotropically (up to ``GroundOptions.max_anisotropy``)."""

    #: ``SHADER`` on a software rasteriser (llvmpipe, softpipe, SwiftShader), else ``DRIVER``
    AUTO = "auto"
    #: the sampler's anisotropic filtering (about free on GPUs, slow on llvmpipe)
    DRIVER = "driver"
    #: up to ``max_anisotropy`` trilinear reads along each footprint, in the shader
    SHADER = "shader"


#: GL_RENDERER substrings of software rasterisers (their own anisotropic filter is slow)
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swiftshader", "swr")


@dataclass(frozen=True)
class GroundOptions:
    """How the ground plane is drawn.

    Attributes
    ----------
    max_anisotropy : float
        Anisotropic filtering of the themes (the driver's cap applies).
    max_supersample : int
        Most weight sub-samples per pixel side.
    mesh : int
        Most quads per side of the height map's mesh.
    anisotropy : Anisotropy
        Whether the driver or the shader (``TT_PROBES``) filters anisotropically.
    base_map : int
        Most texels a side of the base map (:mod:`.base_map`); 0: none.
    """

    max_anisotropy: float = 16.0
    max_supersample: int = 4
    sky: tuple[float, float, float] = field(default=SKY)
    mesh: int = 256
    anisotropy: Anisotropy = Anisotropy.AUTO
    base_map: int = 4096

    def __post_init__(self) -> None:
        if not 1.0 <= float(self.max_anisotropy) <= 64.0:
            raise TerrathemeError(f"max_anisotropy must be 1..64, got {self.max_anisotropy}")
        if not 1 <= int(self.max_supersample) <= 16:
            raise TerrathemeError(f"max_supersample must be 1..16, got {self.max_supersample}")
        if len(self.sky) != 3 or not all(0.0 <= float(c) <= 1.0 for c in self.sky):
            raise TerrathemeError(f"sky must be three values in [0, 1], got {self.sky}")
        if not 0 <= int(self.base_map) <= 16384:
            raise TerrathemeError(f"base_map must be 0..16384 texels a side, got {self.base_map}")
        if not 1 <= int(self.mesh) <= 4096:
            raise TerrathemeError(f"mesh must be 1..4096 quads a side, got {self.mesh}")
