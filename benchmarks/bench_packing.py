"""Benchmark of SFC-packed index layers (issues 2, 15, 19) against the codecs a user would try.

Run ``.venv/bin/python benchmarks/bench_packing.py [--e10-timeout S] [--quick]
[--lookups-only]``;
writes ``benchmarks/results/packing.json`` and ``packing.png``. Needs the
``bench`` extra (imagecodecs: JPEG XL, AVIF, tifffile's zstd).

On the land-cover maps in ../shared/data/maps, all measured in the same run:

* file bytes, bits per texel, encode time and the decode time of the whole
  map: terratheme compact (the smaller of the plane and run-stream payloads)
  and the run streams alone, WebP lossless (OpenCV), JPEG XL lossless
  effort 9 and 10 and AVIF lossless (speed 0) through imagecodecs, a tiled
  GeoTIFF (256 x 256 tiles, zstd level 19, tifffile), PNG level 9 and the
  seed's varint layout; every peer's round trip is checked. Our decode is
  timed to the random-access layer (what a user keeps) and to the dense
  image. JPEG XL effort 10 runs in a subprocess under ``--e10-timeout``
  seconds per map; where it does not finish, it and ours are measured on the
  map's centre crop where it does;
* batched random access, ns per texel for 10^6 random texels, against the
  numpy gather from the dense array and a compiled (numba) dense gather on
  one and two threads, in ``LOOKUP_ROUNDS`` paired rounds (the median ratio
  within a round, and the range); the same batch on the map packed as a
  tiled container of 4096 x 4096 tiles, against the single layer; both
  strategies of ``core.packing.batch`` forced, against the one it picks; and the
  GPU shader's lookups (``core.gpu.PackedGrid.lookup`` on the table as a
  texture, Mesa llvmpipe here: coordinates uploaded, indices read back),
  checked equal to the CPU's;
* scalar lookup time (the layer and the tiled container) against a scalar numpy index;
* pack time (scan + runs + random-access table) with the numpy peer of the
  numba scan on a 4096^2 crop.

Machines are shared: every figure comes with a peer measured in the same run.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import os
import subprocess
import sys
import time
import timeit
from pathlib import Path

import cv2
import matplotlib
import numba
import numpy as np

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from packing_chart import chart  # noqa: E402
from terratheme.core.curves.square import curve_order, hilbert_transposed  # noqa: E402
from terratheme.core.io.images import read_image  # noqa: E402
from terratheme.core.packing import PackedLayer, pack  # noqa: E402
from terratheme.core.packing.batch import STRATEGIES, batch_strategy, lookup_batch  # noqa: E402
from terratheme.core.packing.scalar import quick_cells  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "benchmarks" / "results"
RNG = np.random.default_rng(7)
#: paired rounds of the batched random-access measurement
LOOKUP_ROUNDS = 21
E10_CROP = 2048


def best_of(fn, repeat: int = 3) -> float:
    """Smallest wall time of ``repeat`` calls, seconds."""
    return min(timeit.repeat(fn, number=1, repeat=repeat))


@numba.njit(cache=True, nogil=True)
def dense_gather(img, xs, ys, out):  # pragma: no cover - numba
    """The compiled peer: ``out[k] = img[ys[k], xs[k]]`` on one thread."""
    for k in range(xs.size):
        out[k] = img[ys[k], xs[k]]


@numba.njit(cache=True, nogil=True, parallel=True)
def dense_gather_parallel(img, xs, ys, out):  # pragma: no cover - numba
    """The compiled peer on all cores."""
    for k in numba.prange(xs.size):
        out[k] = img[ys[k], xs[k]]


# ---------------------------------------------------------------- peer codecs


def _imagecodecs():
    # Imported when a peer codec runs: --lookups-only needs neither imagecodecs nor tifffile.
    import imagecodecs

    return imagecodecs


def _geotiff(img: np.ndarray) -> bytes:
    import tifffile

    buf = io.BytesIO()
    tifffile.imwrite(buf, img, tile=(256, 256), compression="zstd",
                     compressionargs={"level": 19})
    return buf.getvalue()


def _geotiff_read(data: bytes) -> np.ndarray:
    import tifffile

    return tifffile.imread(io.BytesIO(data))


def _cv2_read(data: bytes) -> np.ndarray:
    # OpenCV's WebP decoder returns three equal channels for a grey image.
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    return img if img.ndim == 2 else img[:, :, 0]


CODECS = {
    "webp_lossless": (lambda a: cv2.imencode(".webp", a, [cv2.IMWRITE_WEBP_QUALITY, 101])[1]
                      .tobytes(), _cv2_read),
    "jpegxl_e9": (lambda a: _imagecodecs().jpegxl_encode(a, lossless=True, effort=9,
                                                         numthreads=2),
                  lambda d: _imagecodecs().jpegxl_decode(d)),
    "avif_lossless": (lambda a: _imagecodecs().avif_encode(a, level=100, speed=0, numthreads=2),
                      lambda d: _imagecodecs().avif_decode(d)),
    "geotiff_zstd19": (_geotiff, _geotiff_read),
    "png9": (lambda a: cv2.imencode(".png", a, [cv2.IMWRITE_PNG_COMPRESSION, 9])[1].tobytes(),
             _cv2_read),
}

E10_SCRIPT = r"""
import sys, time, numpy as np, imagecodecs
img = np.load(sys.argv[1])
t = time.perf_counter()
data = imagecodecs.jpegxl_encode(img, lossless=True, effort=10, numthreads=2)
enc = time.perf_counter() - t
t = time.perf_counter()
back = imagecodecs.jpegxl_decode(data)
dec = time.perf_counter() - t
assert np.array_equal(np.asarray(back).reshape(img.shape), img)
print(len(data), enc, dec)
"""


def codec_row(name: str, img: np.ndarray) -> dict:
    """Bytes, times and a checked round trip of one peer codec."""
    enc, dec = CODECS[name]
    t = time.perf_counter()
    data = enc(img)
    t_enc = time.perf_counter() - t
    back = np.asarray(dec(data)).reshape(img.shape)
    assert np.array_equal(back, img), name
    t_dec = best_of(lambda: dec(data), 2)
    return {"bytes": len(data), "encode_s": t_enc, "decode_s": t_dec}


def e10_row(img: np.ndarray, timeout: float, work: Path) -> dict | None:
    """JPEG XL effort 10 in a subprocess; None when it does not finish in ``timeout`` s."""
    path = work / "e10.npy"
    np.save(path, img)
    try:
        run = subprocess.run([sys.executable, "-c", E10_SCRIPT, str(path)], capture_output=True,
                             text=True, timeout=timeout, check=True)
    except subprocess.TimeoutExpired:
        return None
    size, enc, dec = run.stdout.split()
    return {"bytes": int(size), "encode_s": float(enc), "decode_s": float(dec)}


def ours_row(img: np.ndarray, fmt: str) -> dict:
    """Our file: bytes, encode (pack + save), load to the random-access layer, and to pixels."""
    t = time.perf_counter()
    layer = pack(img)
    data = layer.to_bytes(format=fmt)
    t_enc = time.perf_counter() - t
    back = PackedLayer.from_bytes(data)
    assert np.array_equal(back.unpack(), img)
    return {"bytes": len(data), "encode_s": t_enc, "encoding": data[5],
            "decode_s": best_of(lambda: PackedLayer.from_bytes(data), 2),
            "decode_dense_s": best_of(lambda: PackedLayer.from_bytes(data).unpack(), 2)}


# ---------------------------------------------------------------- the other peers


def numpy_hilbert_points(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Hilbert points (x, y up) of the 2^n square by recursive numpy concatenation."""
    x = np.zeros(1, np.int32)
    y = np.zeros(1, np.int32)
    for level in range(n):
        h = np.int32(1 << level)
        # Quadrants bottom-left (transposed), top-left, top-right, bottom-right (anti-transposed).
        x, y = (np.concatenate([y, x, x + h, 2 * h - 1 - y]),
                np.concatenate([x, y + h, y + h, h - 1 - x]))
    return x, y


def numpy_scan_runs(img: np.ndarray) -> int:
    """The numpy peer of the numba scan: curve points, keep the image's, gather, run ends."""
    h, w = img.shape
    n = curve_order(w, h)
    x, y = numpy_hilbert_points(n)
    if hilbert_transposed(n):
        x, y = y, x
    keep = (x < w) & (y < h)
    along = img.ravel()[(h - 1 - y[keep]).astype(np.int64) * w + x[keep]]
    return int(np.count_nonzero(np.diff(along)) + 1)


def scan_peer() -> dict:
    """numba scan against the numpy pipeline on a 4096^2 crop of the DRCOG map."""
    path = next((DATA / "maps" / "drcog_lulc").glob("*.png"))
    crop = np.ascontiguousarray(read_image(path)[:4096, :4096, 0])
    runs = numpy_scan_runs(crop)
    assert runs == pack(crop).run_count
    t_np = best_of(lambda: numpy_scan_runs(crop), 3)
    t_nb = best_of(lambda: pack(crop), 3)
    return {"crop": "drcog 4096^2", "numpy_scan_s": t_np, "numba_pack_s": t_nb,
            "numpy_over_numba": t_np / t_nb, "runs": runs}


def lookups(img: np.ndarray, layer: PackedLayer) -> dict:
    """Batched and scalar random access against the dense gathers, in paired rounds."""
    h, w = img.shape
    xs = RNG.integers(0, w, 10**6)
    ys = RNG.integers(0, h, 10**6)
    out = np.empty(xs.size, np.uint8)
    serial = dataclasses.replace(layer, threads=1)
    tiled = pack(img, tile_bits=12)
    tiled_serial = dataclasses.replace(tiled, threads=1)
    for fn in (serial, layer, tiled, tiled_serial):
        assert np.array_equal(fn.lookup(xs, ys), img[ys, xs])
    dense_gather(img, xs, ys, out)
    dense_gather_parallel(img, xs, ys, out)
    gpu = gpu_grid(layer)
    if gpu is not None:
        assert np.array_equal(gpu.lookup(xs, ys), img[ys, xs])  # the shader's = the CPU's
    peers = {
        "numpy_dense": lambda: img[ys, xs],
        "compiled_dense_1t": lambda: dense_gather(img, xs, ys, out),
        "compiled_dense_2t": lambda: dense_gather_parallel(img, xs, ys, out),
        "packed_1t": lambda: serial.lookup(xs, ys),
        "packed_2t": lambda: layer.lookup(xs, ys),
        "tiled_1t": lambda: tiled_serial.lookup(xs, ys),
        "tiled_2t": lambda: tiled.lookup(xs, ys),
        # Both strategies of core.packing.batch forced, to show the one chosen is the faster.
        **{f"{s}_{t}t": (lambda s=s, t=t: lookup_batch(xs, ys, layer.table, out, t, strategy=s))
           for s in STRATEGIES for t in (1, 2)},
        **({"gpu_shader": lambda: gpu.lookup(xs, ys)} if gpu is not None else {}),
    }
    # Paired rounds: on a shared machine the load drifts between rounds, so each ratio is
    # taken within a round, then the median over rounds.
    rounds = {k: [] for k in peers}
    for _ in range(LOOKUP_ROUNDS):
        for k, fn in peers.items():
            rounds[k].append(best_of(fn, 3) * 1e9 / xs.size)
    r = {k: np.array(v) for k, v in rounds.items()}
    rec = {f"{k}_ns": float(np.median(v)) for k, v in r.items()}
    rec["strategy"] = batch_strategy(layer.table)
    for ours, peer in (("packed_2t", "compiled_dense_2t"), ("packed_1t", "compiled_dense_1t"),
                       ("packed_2t", "numpy_dense"), ("packed_1t", "numpy_dense"),
                       ("tiled_1t", "packed_1t"), ("tiled_2t", "packed_2t"),
                       ("gpu_shader", "numpy_dense"),
                       *((f"{s}_{t}t", f"packed_{t}t") for s in STRATEGIES for t in (1, 2))):
        if ours not in r:
            continue
        ratio = r[ours] / r[peer]
        rec[f"{ours}_vs_{peer}"] = float(np.median(ratio))
        rec[f"{ours}_vs_{peer}_range"] = [float(ratio.min()), float(ratio.max())]
    # Scalar calls from Python, paired with numpy's scalar index round by round.
    pts = [(int(x), int(y)) for x, y in zip(xs[:20000], ys[:20000], strict=True)]
    t0 = time.perf_counter()
    layer.lookup(*pts[0])  # builds the quick cells (core.packing.scalar)
    rec["scalar_setup_s"] = time.perf_counter() - t0
    bits, cells = quick_cells(layer.table)
    rec["scalar_cell_bits"] = bits
    rec["scalar_compiled_share"] = float(np.mean([cells[y][x >> bits] == 255 for x, y in pts]))
    tiled.lookup(*pts[0])
    ours, dense, tiles = [], [], []
    for _ in range(LOOKUP_ROUNDS):
        ours.append(best_of(lambda: [layer.lookup(x, y) for x, y in pts], 3) / len(pts) * 1e6)
        dense.append(best_of(lambda: [img[y, x] for x, y in pts], 3) / len(pts) * 1e6)
        tiles.append(best_of(lambda: [tiled.lookup(x, y) for x, y in pts], 3) / len(pts) * 1e6)
    rec["scalar_lookup_us"], rec["scalar_dense_us"] = np.median(ours), np.median(dense)
    rec["scalar_vs_dense"] = float(np.median(np.array(ours) / np.array(dense)))
    rec["scalar_tiled_us"], rec["scalar_tiled_vs_dense"] = float(np.median(tiles)), float(
        np.median(np.array(tiles) / np.array(dense)))
    rec["memory_bytes_per_run"] = layer.memory_bytes / layer.run_count
    rec["dense_bytes"] = int(img.nbytes)
    rec["memory_bytes"] = int(layer.memory_bytes)
    return rec


def gpu_grid(layer: PackedLayer):
    """The layer's table on the GPU (core.gpu.PackedGrid), or None without an OpenGL context."""
    from terratheme.core.gpu import GpuUnavailableError, PackedGrid, gl_context

    try:
        return PackedGrid(gl_context(), layer)
    except GpuUnavailableError as exc:
        print("no GPU lookups:", exc, flush=True)
        return None


def measure(name: str, img: np.ndarray, e10_timeout: float, work: Path, quick: bool) -> dict:
    """All measurements of one map."""
    h, w = img.shape
    rec: dict = {"name": name, "width": w, "height": h, "load_average": os.getloadavg()}
    print(name, "ours", flush=True)
    for fmt in ("compact", "streams", "seed"):
        rec[f"terratheme_{fmt}"] = ours_row(img, fmt)
    for codec in CODECS:
        if quick and codec in ("jpegxl_e9", "avif_lossless"):
            continue
        print(name, codec, flush=True)
        rec[codec] = codec_row(codec, img)
    if not quick:
        print(name, "jpegxl_e10", flush=True)
        e10 = e10_row(img, e10_timeout, work)
        rec["jpegxl_e10"] = e10 if e10 is not None else {"timeout_s": e10_timeout}
        if e10 is None:
            # Where effort 10 finishes: the map's centre crop, ours on the same crop.
            y0, x0 = (h - E10_CROP) // 2, (w - E10_CROP) // 2
            crop = np.ascontiguousarray(img[y0: y0 + E10_CROP, x0: x0 + E10_CROP])
            rec["e10_crop"] = {"size": E10_CROP, "jpegxl_e10": e10_row(crop, e10_timeout, work),
                               "jpegxl_e9": codec_row("jpegxl_e9", crop),
                               "avif_lossless": codec_row("avif_lossless", crop),
                               "terratheme_compact": ours_row(crop, "compact")}
    for row in rec.values():
        if isinstance(row, dict) and "bytes" in row:
            row["bits_per_texel"] = 8 * row["bytes"] / (w * h)
    for row in rec.get("e10_crop", {}).values():
        if isinstance(row, dict) and "bytes" in row:
            row["bits_per_texel"] = 8 * row["bytes"] / E10_CROP**2
    codecs = [k for k in ("jpegxl_e10", "avif_lossless") if "bytes" in rec.get(k, {})]
    if codecs:
        best = min(rec[k]["bytes"] for k in codecs)
        rec["compact_vs_best_of_e10_avif"] = rec["terratheme_compact"]["bytes"] / best
    return measure_lookups(rec, img)


def measure_lookups(rec: dict, img: np.ndarray) -> dict:
    """Pack time and random access of one map, into its record."""
    print(rec["name"], "lookups", flush=True)
    layer = pack(img)
    rec.update(runs_hilbert=layer.run_count, pack_s=best_of(lambda: pack(img), 3),
               load_average=os.getloadavg(), **lookups(img, layer))
    return rec


def main() -> None:
    """Run everything and write the results."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--e10-timeout", type=float, default=900.0,
                        help="seconds JPEG XL effort 10 may take per map (default 900)")
    parser.add_argument("--quick", action="store_true",
                        help="skip JPEG XL and AVIF (the slow encoders)")
    parser.add_argument("--lookups-only", action="store_true",
                        help="rerun pack time and the lookups (all their peers) only, keeping "
                             "the codec rows of the last results")
    args = parser.parse_args()
    if args.lookups_only:
        # The last results, their pack time and random access measured again.
        result = json.loads((OUT / "packing.json").read_text())
        for rec in result["maps"]:
            path = next((DATA / "maps" / rec["name"]).glob("*.png"))
            measure_lookups(rec, np.ascontiguousarray(read_image(path)[:, :, 0]))
        result["load_average_at_end"] = os.getloadavg()
        (OUT / "packing.json").write_text(json.dumps(result, indent=1))
        return chart(result["maps"], OUT / "packing.png")
    OUT.mkdir(parents=True, exist_ok=True)
    work = OUT / ".work"
    work.mkdir(exist_ok=True)
    maps = []
    for folder in sorted((DATA / "maps").iterdir()):
        for path in sorted(folder.glob("*.png")):
            img = np.ascontiguousarray(read_image(path)[:, :, 0])
            rec = measure(folder.name, img, args.e10_timeout, work, args.quick)
            maps.append(rec)
            print(json.dumps(rec), flush=True)
    peer = scan_peer()
    print(json.dumps(peer), flush=True)
    result = {"maps": maps, "scan_peer": peer, "load_average_at_end": os.getloadavg(),
              "note": "bytes; times in s, ns per texel, us per scalar call; ratios vs peers "
                      "measured in the same run on a shared 2-core machine"}
    (OUT / "packing.json").write_text(json.dumps(result, indent=1))
    for f in work.iterdir():
        f.unlink()
    work.rmdir()
    chart(maps, OUT / "packing.png")


if __name__ == "__main__":
    main()
