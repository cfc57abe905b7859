"""Options of the low-angle terrain preview (DESIGN.md section 3).

One small frozen dataclass, :class:`FilterOptions`, chooses the filter and
its knobs; :class:`Method` names the seed's parallelogram filter and the
baselines it is compared with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from core.errors import TerrathemeError


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

    Parameters
    ----------
    method : Method
        The filter.
    max_anisotropy : float
        Largest footprint elongation honoured (GPU/pbrt style clamp); longer
        footprints are widened across. For ``PARALLELOGRAM`` it also decides
        how many skewed copies are prefiltered: ``lambda = H/L`` up to the
        next power of two, ``2^k`` (the two-probe lookup honours ``2^(k+1)``).
        The clamp acts on the pixel's own footprint, like EWA's, and a
        footprint longer than the wrapping texture (near the horizon) is read
        as one texture length widened across by the same factor (same area;
        its turns lie side by side): before, ``H`` was cut to ``N`` first, so
        the horizon rows read a thin band instead of nearly the texture's
        mean (up to 20x EWA's error there); fixing it gained 0.9-1.2 dB on the
        thematic texture at pitches 2.5-10 (0 on the checkerboard; benchmarks/
        results/perspective.json).
        ``ANISO`` takes at most this many probes.
    aperture : float
        Scale of the pixel footprint fed to the filters (1.0 = the pixel's
        own parallelogram of eq. 2; the seed's 2 x 2-pixel filter is 2.0).
        Applies to ``PARALLELOGRAM``, ``TRILINEAR`` and ``ANISO``.
    skew_oversampling : int
        Power of two: how many times more skews per ``lambda`` level than the
        seed's ``lambda`` (1 = the seed). More skews, more memory. Default 1:
        2 doubles the family for 0.1-0.2 dB (benchmarks/results/perspective.json,
        ``parallelogram-dense``).
    long_oversampling : int
        Power of two: how many times more samples along a copy's long side
        than the seed's ``N/H`` (1 = the seed), never closer than ``L`` apart.
        More samples, more memory. Default 2: with the seed's lattice, edges
        across the long side show the bilinear ripple of a too coarse lattice
        (about 3 dB lost); 4 gains another 1-2 dB on the checkerboard for 1.7x
        the memory. Defaults cost 43 bytes per RGB uint8 texel (mip pyramid: 4).
    long_probes : int
        ``PARALLELOGRAM`` only. 1: the seed's eq. 5, three copies blended by
        the mantissas of ``H`` and ``L`` (12 reads). 2: two probes of the
        copy below ``H`` spanning exactly ``H`` along the long side (4-16
        reads, see :func:`core.perspective.lookup.two_probe_kernel`); default,
        measured 0.5-1.3 dB closer to the reference at grazing angles. Where
        the long side is under 2 texels and the footprint anisotropic, copy
        ``2^0`` is the bare texture, so the probes sit at ``+-sigma`` of the
        pixel's box along the long side: another 0.3-0.7 dB on the
        checkerboard and 0.6-1.3 dB on the thematic texture at pitches <= 20
        for 7.6-8.5 reads instead of 5.7-7.2 (the ``H < 1`` pixels were a
        single bilinear read before).
    skew_blend : bool
        ``PARALLELOGRAM`` only. Interpolate between the two prefiltered skews
        around the footprint's ``tan`` (linear in ``tan``, as eq. 5 is in
        ``H`` and ``L``) instead of reading the nearest one. Measured +0.3 to
        +0.6 dB at pitches <= 20 on both textures for 9-11.5 reads instead of
        7.6-8.5 and about 1.1x the time; default off (the default already
        beats EWA by 1.3-5.3 dB with fewer reads).
    sky : tuple of float
        Colour of pixels above the horizon (``z <= 0``), in the texture's
        value scale (integers are read as [0, 1]).
    reference_density : float
        ``REFERENCE`` only: sub-samples per texel of footprint along each
        screen axis.
    reference_min_samples, reference_max_samples : int
        ``REFERENCE`` only: bounds on sub-samples per pixel along each axis.
    """

    method: Method = Method.PARALLELOGRAM
    max_anisotropy: float = 16.0
    aperture: float = 1.0
    skew_oversampling: int = 1
    long_oversampling: int = 2
    long_probes: int = 2
    skew_blend: bool = False
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
                f"unknown filter method {self.method!r} (choose from {names})"
            ) from None
        if not (math.isfinite(self.max_anisotropy) and 1.0 <= self.max_anisotropy <= 4096):
            raise TerrathemeError(
                f"max_anisotropy must be in [1, 4096], got {self.max_anisotropy}"
            )
        if not (math.isfinite(self.aperture) and 0.0 < self.aperture <= 16.0):
            raise TerrathemeError(f"aperture must be in (0, 16], got {self.aperture}")
        for name in ("skew_oversampling", "long_oversampling"):
            val = getattr(self, name)
            s = int(val)
            if s != val or s < 1 or s > 16 or s & (s - 1):
                raise TerrathemeError(f"{name} must be a power of two in [1, 16], got {val}")
        if self.long_probes not in (1, 2):
            raise TerrathemeError(f"long_probes must be 1 or 2, got {self.long_probes}")
        if not isinstance(self.skew_blend, bool):
            raise TerrathemeError(f"skew_blend must be True or False, got {self.skew_blend!r}")
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
        """``k``: the parallelogram family holds ``lambda = H/L`` up to ``2**k``."""
        return max(0, math.ceil(math.log2(self.max_anisotropy) - 1e-9))
