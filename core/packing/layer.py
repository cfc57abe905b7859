"""The packed index layer in memory (seed section 2.1): header, palette, runs.

A :class:`PackedLayer` answers texel reads without unpacking (:meth:`lookup`),
rebuilds the image whole (:meth:`unpack`) or band by band (:meth:`bands`), and
saves to / loads from the file encodings of :mod:`core.packing.container`.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from terratheme.core.curves.fill import fill_runs, fill_window
from terratheme.core.curves.scan import check_run_ends, ranks_to_steps, steps_to_ranks
from terratheme.core.curves.square import Curve, curve_order
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.inputs import check_input_file
from terratheme.core.packing.batch import lookup_batch
from terratheme.core.packing.container import (
    LayerFields,
    decode_layer,
    encode_layer,
    read_layer_file,
)
from terratheme.core.packing.layout import W_COUNT, W_GRID_BITS, W_LEVELS
from terratheme.core.packing.lookup import build_table, scalar_lookup_function, table_runs
from terratheme.core.packing.palette import (
    PaletteReport,
    as_palette,
    check_colours,
    palette_values,
    scalar_values,
)
from terratheme.core.packing.scalar import quick_cells

_SCALAR_TYPES = frozenset({np.int64, np.int32, np.int16, np.uint16, np.uint32, np.uint8})
#: Batches at least this large are looked up on all threads.
PARALLEL_FROM = 1 << 16


@dataclass(frozen=True, eq=False)
class PackedLayer:
    """An index layer as runs along a space-filling curve.

    Build one with :func:`core.packing.pack`, :meth:`from_runs` or :meth:`load`.

    Attributes
    ----------
    palette : (K, C) uint8 or uint16 ndarray
        Colour of each palette index (``K <= 256``).
    identity : bool
        Single-channel layer whose palette index is the pixel value.
    squeeze : bool
        The packed image was 2-D: reads drop the channel axis.
    colours : (K, 3|4) uint8 ndarray or None
        Display colours of an identity layer's indices.
    threads : int
        Threads for batched lookups of at least ``PARALLEL_FROM`` texels.
    S, P : (R,) ndarrays
        The seed's runs: 1-based step of each run's last texel, palette index.
    """

    width: int
    height: int
    curve: Curve
    palette: np.ndarray
    identity: bool
    squeeze: bool
    _data: np.ndarray = field(repr=False)
    _scalars: list = field(repr=False)
    _quick: tuple = field(default=(), init=False, repr=False)  # built by _quick_setup
    report: PaletteReport | None = None
    colours: np.ndarray | None = None
    threads: int = 2

    # ------------------------------------------------------------ construction

    @classmethod
    def from_runs(
        cls, width: int, height: int, curve: str | Curve, steps: np.ndarray,
        indices: np.ndarray, palette: np.ndarray, *, identity: bool = False,
        squeeze: bool = False, report: PaletteReport | None = None, one_based: bool = False,
        colours: np.ndarray | None = None,
    ) -> PackedLayer:
        """A layer from its runs ``D_i = <S_i, P_i>`` (seed Table 3).

        ``steps`` (R,) are each run's last step, strictly increasing, 0-based unless
        ``one_based``, ending at the last texel; ``indices`` (R,) index ``palette`` (K,) or
        (K, C). ``colours`` (K' >= K, 3|4) uint8 are an identity layer's display colours.
        Raises TerrathemeError for runs that break those rules or colours that do not fit.
        """
        curve = Curve.parse(curve)
        n = curve_order(width, height)
        steps = np.asarray(steps, dtype=np.int64) - (1 if one_based else 0)
        indices = np.asarray(indices)
        palette = as_palette(palette)
        if steps.ndim != 1 or steps.shape != indices.shape or steps.size == 0:
            raise TerrathemeError(f"runs: {steps.shape} steps and {indices.shape} indices")
        if indices.min() < 0 or indices.max() >= palette.shape[0]:
            raise TerrathemeError(
                f"palette index {int(indices.max())} out of range: the palette has "
                f"{palette.shape[0]} colours"
            )
        check_run_ends(steps, width, height, curve)
        colours = check_colours(colours, palette.shape[0], identity)
        data = build_table(width, height, n, curve is Curve.MORTON, steps, indices)
        palette = np.ascontiguousarray(palette)
        palette.setflags(write=False)
        scalars = scalar_values(palette, bool(squeeze))
        return cls(int(width), int(height), curve, palette, bool(identity), bool(squeeze),
                   data, scalars, report, colours)

    @classmethod
    def from_lengths(
        cls, width: int, height: int, curve: str | Curve, lengths: np.ndarray,
        indices: np.ndarray, palette: np.ndarray, **kwargs: object,
    ) -> PackedLayer:
        """A layer from run lengths in texels (the file's form, seed section 2.4).

        Raises TerrathemeError for a zero length or lengths not adding up to ``width * height``.
        """
        lengths = np.asarray(lengths, dtype=np.int64)
        if lengths.size == 0 or lengths.min() < 1:
            raise TerrathemeError("run lengths must be at least 1")
        ends = np.cumsum(lengths)
        if ends[-1] != width * height:
            raise TerrathemeError(
                f"run lengths cover {int(ends[-1])} texels but the image has "
                f"{width} x {height} = {width * height}"
            )
        steps = ranks_to_steps(ends, width, height, curve)
        return cls.from_runs(width, height, curve, steps, indices, palette, **kwargs)

    # ------------------------------------------------------------ the runs

    @property
    def run_count(self) -> int:
        """Number of runs ``R``."""
        return int(self._data[W_COUNT])

    @property
    def P(self) -> np.ndarray:
        """(R,) uint8 ndarray: palette index of each run (seed Table 3)."""
        return table_runs(self._data)[1]

    @property
    def steps(self) -> np.ndarray:
        """(R,) uint32 ndarray: 0-based curve step of each run's last texel."""
        return table_runs(self._data)[0]

    @property
    def S(self) -> np.ndarray:
        """(R,) int64 ndarray: the seed's 1-based step of each run's last texel (Table 3)."""
        return self.steps.astype(np.int64) + 1

    @property
    def lengths(self) -> np.ndarray:
        """(R,) int64 ndarray: image texels in each run (the file's run lengths)."""
        ends = steps_to_ranks(self.steps, self.width, self.height, self.curve)
        return np.diff(ends, prepend=0)

    @property
    def channels(self) -> int:
        """Colour channels of a texel (1, 3 or 4)."""
        return int(self.palette.shape[1])

    @property
    def table(self) -> np.ndarray:
        """The random-access ``uint32`` table, read-only (:mod:`core.packing.layout`; GPU shaders
        read it).
        """
        view = self._data.view()
        view.setflags(write=False)
        return view

    def with_grid_bits(self, bits: int) -> PackedLayer:
        """The same layer, its table's grid blocks ``2^bits`` a side (at most the curve's)."""
        if int(self._data[W_GRID_BITS]) == min(int(bits), int(self._data[W_LEVELS])):
            return self
        steps, indices = table_runs(self._data)
        data = build_table(self.width, self.height, int(self._data[W_LEVELS]),
                           self.curve is Curve.MORTON, steps, indices, bits)
        return dataclasses.replace(self, _data=data)

    def with_table(self, table: np.ndarray) -> PackedLayer:
        """The same layer over another copy of its table (e.g. a view into a larger array)."""
        if table.dtype != np.uint32 or not np.array_equal(table, self._data):
            raise TerrathemeError("with_table needs an exact copy of the layer's table")
        return dataclasses.replace(self, _data=table)

    @property
    def memory_bytes(self) -> int:
        """Bytes of the random-access structure (header, directory, one word per run)."""
        return int(self._data.nbytes)

    # ------------------------------------------------------------ reading texels

    def lookup(self, xs: np.ndarray | int, ys: np.ndarray | int) -> np.ndarray:
        """Texel values at columns ``xs``, rows ``ys`` (row 0 = top, broadcast), without unpacking.

        The same as ``image[ys, xs]`` on the packed image; TerrathemeError outside it.
        """
        if type(xs) is int and type(ys) is int:
            # Scalar fast path (:mod:`.scalar`): a uniform quick cell's byte (most texels),
            # else one compiled call; then the ready-made value (like image[y, x]). Kept
            # short (docs/decisions.md), the rest in _lookup_many.
            try:
                rows, bits, w, values, call, data = self._quick
            except ValueError:  # () until the first scalar lookup builds the cells
                rows, bits, w, values, call, data = self._quick_setup()
            # Bounds: one test for both signs and x's end; a row past the end is not in rows.
            if (xs | ys) >= 0 and xs < w:
                try:
                    i = rows[ys][xs >> bits]
                except IndexError:
                    raise TerrathemeError(self._outside(xs, ys)) from None
                return values[i] if i != 255 else values[call(xs, ys, data)]
            raise TerrathemeError(self._outside(xs, ys))
        return self._lookup_many(xs, ys)

    def _lookup_many(self, xs: np.ndarray | int, ys: np.ndarray | int) -> np.ndarray:
        # lookup() of numpy scalars and arrays.
        if type(xs) in _SCALAR_TYPES and type(ys) in _SCALAR_TYPES:
            return self.lookup(int(xs), int(ys))
        xs_arr = np.asarray(xs)
        ys_arr = np.asarray(ys)
        if xs_arr.dtype.kind not in "iu" or ys_arr.dtype.kind not in "iu":
            raise TerrathemeError("texel coordinates must be integers")
        xs_b, ys_b = np.broadcast_arrays(xs_arr, ys_arr)
        shape = xs_b.shape
        flat_x = np.ascontiguousarray(xs_b.reshape(-1), dtype=np.int64)
        flat_y = np.ascontiguousarray(ys_b.reshape(-1), dtype=np.int64)
        idx = np.empty(flat_x.size, dtype=np.uint8)
        threads = self.threads if flat_x.size >= PARALLEL_FROM else 1
        bad = lookup_batch(flat_x, flat_y, self._data, idx, threads)
        if bad >= 0:
            raise TerrathemeError(self._outside(flat_x[bad], flat_y[bad]))
        values = self.values_of(idx)
        out = values.reshape(shape + values.shape[1:])
        return out[()] if out.ndim == 0 else out

    def _quick_setup(self) -> tuple:
        # What the scalar path reads, built on its first call (:func:`.scalar.quick_cells`).
        bits, rows = quick_cells(self._data)
        quick = (rows, bits, self.width, self._scalars, scalar_lookup_function(), self._data)
        object.__setattr__(self, "_quick", quick)
        return quick

    def _outside(self, x: int, y: int) -> str:
        return f"texel ({int(x)}, {int(y)}) is outside the {self.width} x {self.height} layer"

    def unpack(self, *, indices_only: bool = False) -> np.ndarray:
        """The whole image back, as packed; ``indices_only``: the (H, W) uint8 index image."""
        steps, indices = table_runs(self._data)
        idx = fill_runs(steps, indices, self.width, self.height, self.curve)
        return idx if indices_only else self.values_of(idx)

    def bands(self, rows: int = 256) -> Iterator[tuple[int, np.ndarray]]:
        """``(y, band)`` of the (h, width) uint8 index image, ``rows`` a band, top to bottom.

        Memory stays at one band: the same buffer is reused from band to band.
        """
        steps, indices = table_runs(self._data)
        rows = max(1, int(rows))
        buf = np.empty((min(rows, self.height), self.width), np.uint8)
        for y in range(0, self.height, rows):
            h = min(rows, self.height - y)
            yield y, fill_window(steps, indices, self.width, self.height, self.curve, 0, y,
                                 self.width, h, out=buf[:h], threads=self.threads)

    def values_of(self, indices: np.ndarray) -> np.ndarray:
        """Texel values of palette indices, as :meth:`unpack` returns them."""
        return palette_values(self.palette, self.identity, self.squeeze, indices)

    # ------------------------------------------------------------ files

    def save(self, path: str | os.PathLike, *, format: str = "compact") -> int:
        """Write the layer atomically in ``format`` (:func:`.container.encode_layer`); returns the
        bytes written.
        """
        data = self.to_bytes(format=format)
        write_bytes_atomic(path, data)
        return len(data)

    def to_bytes(self, *, format: str = "compact") -> bytes:
        """The file content :meth:`save` would write."""
        return encode_layer(LayerFields(self.width, self.height, self.curve, self.lengths,
                                        self.P, self.palette, self.identity, self.squeeze,
                                        self.colours), format)

    @classmethod
    def load(cls, path: str | os.PathLike) -> PackedLayer:
        """Read a layer file; CorruptFileError if damaged, UnsupportedVersionError if newer."""
        p = os.fspath(check_input_file(path, "a packed layer"))
        with open(p, "rb") as fh:
            data = read_layer_file(fh, name=p)
        return cls.from_bytes(data, name=p)

    @classmethod
    def from_bytes(cls, data: bytes, *, name: str = "<bytes>") -> PackedLayer:
        """Parse the content of a layer file."""
        f = decode_layer(data, name=name)
        try:
            return cls.from_lengths(f.width, f.height, f.curve, f.lengths, f.indices, f.palette,
                                    identity=f.identity, squeeze=f.squeeze, colours=f.colours)
        except CorruptFileError:
            raise
        except TerrathemeError as exc:
            raise CorruptFileError(f"{name}: {exc}") from None

