"""The enclosing square of an image and the curve kinds (no numba: cheap to import).

A layer of ``width x height`` texels is scanned along a curve over the
smallest ``2^n x 2^n`` square holding it (seed sfc_packing.txt, section 1);
:func:`curve_order` gives ``n``. File readers check sizes against
:data:`MAX_SIDE` with this module alone, so ``terratheme info`` loads no kernel.
"""

from __future__ import annotations

import enum

from terratheme.core.errors import TerrathemeError

#: Largest side of one curve's square: 2^32 steps, 0-based steps fit uint32.
MAX_SIDE = 65536


class Curve(enum.IntEnum):
    """Curve type, as stored in the file header (seed Table 1)."""

    HILBERT = 0
    MORTON = 1

    @classmethod
    def parse(cls, value: str | int | Curve) -> Curve:
        """``"hilbert"`` / ``"morton"`` (any case), an int code, or a Curve."""
        if isinstance(value, Curve):
            return value
        if isinstance(value, str):
            try:
                return cls[value.strip().upper()]
            except KeyError:
                raise TerrathemeError(
                    f"unknown curve {value!r}: use 'hilbert' or 'morton'"
                ) from None
        try:
            return cls(int(value))
        except ValueError:
            raise TerrathemeError(f"unknown curve code {value!r}") from None


def curve_order(width: int, height: int) -> int:
    """Levels ``n`` of the enclosing ``2^n x 2^n`` square (0 for 1 x 1; sides 1 .. 65536)."""
    width, height = int(width), int(height)
    if width < 1 or height < 1:
        raise TerrathemeError(f"image of {width} x {height} texels has no texels to scan")
    if width > MAX_SIDE or height > MAX_SIDE:
        raise TerrathemeError(
            f"image of {width} x {height} texels exceeds the {MAX_SIDE} x {MAX_SIDE} limit"
        )
    return int(max(width, height) - 1).bit_length()


def hilbert_transposed(n: int) -> bool:
    """Whether the image curve swaps x and y (even ``n``): first move up (design.md §4)."""
    return n % 2 == 0
