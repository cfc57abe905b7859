"""Options of the low-angle terrain preview (design.md §6).

One small frozen dataclass, :class:`FilterOptions`, chooses the filter and
its knobs; :class:`Method` names the seed's parallelogram filter and the
baselines it is compared with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from terratheme.core.errors import TerrathemeError


class Method(StrEnum):
    """Texture filter used for each screen pixel."""

    PARALLELOGRAM = "parallelogram"  # the seed's method, eqs. 2-9
    NEAREST = "nearest"  # texel containing (U, V), no filtering
    BILINEAR = "bilinear"  # four texels of the input, no prefiltering
    TRILINEAR = "trilinear"  # mip-mapping, the seed's "diagonal" H = L
    ANISO = "aniso"  # GPU style: up to max_anisotropy trilinear probes
    EWA = "ewa"  # Heckbert's elliptical weighted average, as pbrt-v4 does it
    REFERENCE = "reference"  # supersampled box filter over the pixel


#: methods that need a mip pyramid of the power-of-two texture
PYRAMID_METHODS = frozenset({Method.TRILINEAR, Method.ANISO, Method.EWA})


@dataclass(frozen=True)
class FilterOptions:
    """How a frame is filtered.

    ``max_anisotropy``: ``PARALLELOGRAM`` cells up to this elongation (``lambda =
    2^ceil(log2)``; footprints about ``cells_per_footprint`` times longer are read sharp),
    ``ANISO`` takes at most this many probes, ``EWA`` clamps its ellipse's eccentricity.
    ``aperture``: scale of the pixel footprint (1: eq. 2's parallelogram; the seed's
    2 x 2-pixel filter: 2). ``skew_oversampling``: 1 or 2 times the seed's skews (2 doubles
    the memory). ``cells_per_footprint``: ``PARALLELOGRAM`` spans this to twice this many
    cells along (sharper ends, more reads). ``sky``: colour above the horizon in [0, 1].
    ``reference_*``: ``REFERENCE`` sub-samples per texel of footprint along each screen
    axis, within the bounds.
    """

    method: Method = Method.PARALLELOGRAM
    max_anisotropy: float = 16.0
    aperture: float = 1.0
    skew_oversampling: int = 1
    cells_per_footprint: float = 3.0
    sky: tuple[float, ...] = (0.62, 0.74, 0.88)
    reference_density: float = 2.0
    reference_min_samples: int = 4
    reference_max_samples: int = 256

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "method", Method(self.method))
        except ValueError:
            names = ", ".join(m.value for m in Method)
            raise TerrathemeError(
                f"unknown filter method {self.method!r} (choose from {names})") from None
        if not (math.isfinite(self.max_anisotropy) and 1.0 <= self.max_anisotropy <= 4096):
            raise TerrathemeError(
                f"max_anisotropy must be in [1, 4096], got {self.max_anisotropy}"
            )
        if not (math.isfinite(self.aperture) and 0.0 < self.aperture <= 16.0):
            raise TerrathemeError(f"aperture must be in (0, 16], got {self.aperture}")
        if self.skew_oversampling not in (1, 2) or isinstance(self.skew_oversampling, bool):
            raise TerrathemeError(
                f"skew_oversampling must be 1 or 2, got {self.skew_oversampling}")
        if not (math.isfinite(self.cells_per_footprint) and 1.0 <= self.cells_per_footprint <= 16):
            raise TerrathemeError(
                f"cells_per_footprint must be in [1, 16], got {self.cells_per_footprint}")
        if len(self.sky) == 0 or not all(math.isfinite(c) for c in self.sky):
            raise TerrathemeError(f"sky colour must be finite numbers, got {self.sky}")
        if not (self.reference_density > 0 and math.isfinite(self.reference_density)):
            raise TerrathemeError(
                f"reference_density must be positive, got {self.reference_density}"
            )
        if not 1 <= self.reference_min_samples <= self.reference_max_samples <= 4096:
            raise TerrathemeError(
                "need 1 <= reference_min_samples <= reference_max_samples <= 4096, got "
                f"{self.reference_min_samples}, {self.reference_max_samples}"
            )

    @property
    def max_lambda_log2(self) -> int:
        """``k``: the family keeps cells with ``lambda = H/L`` up to ``2**k``."""
        return max(0, math.ceil(math.log2(self.max_anisotropy) - 1e-9))
