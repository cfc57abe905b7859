"""The summaries of ``bench_scale.py``: paired ratios and the 400 x 400 km estimate."""

from __future__ import annotations

import numpy as np
from terratheme.core.model.colour_map import MAP_TILE, ColourMap

REGION_PIXELS = 400_000 * 400_000  # 400 x 400 km at 1 m


def pairs(result: dict) -> list[dict]:
    """Each 2-worker run at the main tile against the serial run next to it in time."""
    out = []
    for r in result["records"]:
        if r["workers"] != 2 or r["tile"] != result["tile"]:
            continue
        near = [s for s in result["records"] if s["side"] == r["side"] and s["workers"] == 0
                and abs(s["order"] - r["order"]) == 1]
        for s in near[:1]:
            out.append({
                "side": r["side"], "orders": [s["order"], r["order"]],
                "tile_ratio": r["tile_mpx_per_s"] / s["tile_mpx_per_s"],
                "end_to_end_ratio": r["mpx_per_s"] / s["mpx_per_s"],
                "cpu_per_mpx_ratio": s["tile_cpu_s_per_mpx"] / r["tile_cpu_s_per_mpx"],
                "cores_obtained": [s["cores_obtained"], r["cores_obtained"]],
                # The serial peer's CPU seconds per wall second in its tile stages, and the
                # tile ratio 2 workers would reach on both cores whole at their own CPU cost
                # per megapixel: above 1.7 only if the peer uses under 2 / 1.7 cores.
                "serial_cpu_s_per_wall_s": s["cores_obtained"],
                "tile_ratio_cap_on_2_cores": 2 / s["cores_obtained"]
                * s["tile_cpu_s_per_mpx"] / r["tile_cpu_s_per_mpx"],
                "load_at_start": [s["load_before"][0], r["load_before"][0]],
            })
    return out


def estimate(result: dict) -> dict:
    """Hours and bytes of a 400 x 400 km region at 1 m from the largest photo's figures."""
    big = max(r["side"] for r in result["records"])
    runs = [r for r in result["records"] if r["side"] == big and r["tile"] == result["tile"]]
    two = [r for r in runs if r["workers"] == 2]
    serial = next(r for r in runs if r["workers"] == 0)
    rend = next(r for r in result["renders"] if r["side"] == big)
    px = serial["pixels"]
    # Per worker: the measured 2-worker tile rate halved (on this shared machine), and the
    # rate of one dedicated core from the workers' CPU seconds per megapixel.
    shared_rate = np.mean([r["tile_mpx_per_s"] for r in two]) * 1e6 / 2
    worker_cpu = np.mean([sum(c["workers"] for c in r["stage_cpu_seconds"]) for r in two])
    core_rate = px / worker_cpu
    client_per_px = np.mean([r["client_tile_cpu_s_per_mpx"] for r in two]) / 1e6
    client = np.mean([r["client_seconds"] for r in two])
    counts = (1, 2, 8, 32, 128)
    cell, cmap_scale = serial["cell"], serial["colour_map_scale"]
    vertices = (400_000 // cell + 1) ** 2
    map_side = -(-400_000 // cmap_scale)
    map_pixels = map_side**2

    def hours(rate: float, n: int) -> float:
        # The client's serial part, then the tiles on n workers or the client's own share.
        return (client + REGION_PIXELS * max(1 / (n * rate), client_per_px)) / 3600

    return {
        "assumptions": "tiles run on N workers of one thread each at the per-worker rate "
                       "(shared: the 2-worker run's tile rate halved, on this loaded machine; "
                       "dedicated core: from the workers' CPU seconds per megapixel); the "
                       "client's serial part (theme fit and cell/colour scale on the centre "
                       "2048^2 window) is the 2-worker run's, independent of the region; the "
                       "client's CPU per tile (scheduling, sink; a local cluster's scheduler "
                       "runs in the client process) bounds the rate at 1 / client_cpu_per_px "
                       "whatever N; the render runs on one machine; "
                       "bytes scale per vertex and map pixel from the largest photo (a "
                       "mosaic of 512-px crops, busier than real land, so the packed layer "
                       "is an upper estimate); the photo is read once from a shared file "
                       "system fast enough",
        "measured_on_side": big,
        "per_worker_tile_mpx_per_s_shared": shared_rate / 1e6,
        "per_worker_tile_mpx_per_s_dedicated_core": core_rate / 1e6,
        "client_tile_cpu_s_per_mpx": client_per_px * 1e6,
        "client_bound_mpx_per_s": 1 / client_per_px / 1e6 if client_per_px else None,
        # The client's (and the in-process dask scheduler's) CPU per megapixel falls with
        # fewer, larger tiles: the 2-worker runs of the smallest photo at every tile.
        "client_tile_cpu_s_per_mpx_by_tile": {
            r["tile"]: r["client_tile_cpu_s_per_mpx"] for r in result["records"]
            if r["workers"] == 2 and r["side"] == min(x["side"] for x in result["records"])},
        "client_seconds": client,
        "convert_hours_on_n_workers_shared": {n: hours(shared_rate, n) for n in counts},
        "convert_hours_on_n_workers_dedicated": {n: hours(core_rate, n) for n in counts},
        # Whole-region arrays on the client only: the grid, the colour map's stored gain and
        # coverage (a worker gets its tile's window of the grid, so its peak is the measured one).
        "worker_peak_rss_mib": max(max(r["worker_peak_rss_mib"]) for r in two),
        "client_peak_rss_mib": max(r["client_peak_rss_mib"] for r in two)
        + (vertices + 4 * map_pixels) / 2**20,
        "render_hours_one_machine": REGION_PIXELS / (rend["mpx_per_s"] * 1e6) / 3600,
        "bytes": {
            "grid_vertices": vertices,
            "packed_layer": serial["packed_bytes"] / np.prod(serial["grid_shape"]) * vertices,
            "colour_map": serial["colour_map_bytes"] / np.prod(serial["colour_map_shape"])
            * map_pixels,
            "themes": serial["theme_bytes"],
            # Beyond JPEG XL level 5 (2^28 pixels) the map ships in MAP_TILE^2 tiles.
            "colour_map_tiles": 1 if ColourMap.fits_one_image((map_side, map_side), "jpegxl")
            else int(np.prod(ColourMap.tile_counts((map_side, map_side), MAP_TILE))),
            "rendered_geotiff": rend["file_bytes"] * REGION_PIXELS / rend["texels"],
            "photo_rgb_raw": 3 * REGION_PIXELS,
        },
    }
