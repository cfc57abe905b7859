"""Make the bundled sample maps: index images (PNG) and their projects (.ttproj).

Run: ``.venv/bin/python sample_maps/make_samples.py``

Each map is drawn by hand in code (shapes, seeded wobble) on a vertex grid;
``<name>.png`` is a single-channel index image (pixel = index into the
theme list in ``samples.json``), ``<name>.ttproj`` the project made from it
with the shipped themes (the same path as ``terratheme new``), and
``<name>_preview.png`` a quarter-scale overview render.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from terratheme.core.io.atomic import write_bytes_atomic  # noqa: E402
from terratheme.core.io.images import write_image  # noqa: E402
from terratheme.core.model.index_image import project_from_index_image  # noqa: E402
from terratheme.core.model.project import save_project  # noqa: E402
from terratheme.core.render.project import render_project  # noqa: E402
from terratheme.core.themes.library import shipped_theme_library  # noqa: E402

W, H = 97, 73  # vertices: 96 x 72 cells of 16 x 16 -> 1536 x 1152 texels
CELL = (16, 16)


def wobble(rng: np.random.Generator, n: int, amp: float, smooth: float) -> np.ndarray:
    """(n,) smooth random offsets."""
    w = ndimage.gaussian_filter1d(rng.standard_normal(n), smooth, mode="wrap")
    return amp * w / (np.abs(w).max() + 1e-9)


def blobs(rng: np.random.Generator, shape: tuple[int, int], smooth: float) -> np.ndarray:
    """Smooth random field in [0, 1]."""
    f = ndimage.gaussian_filter(rng.standard_normal(shape), smooth)
    return (f - f.min()) / (f.max() - f.min())


def coastline(rng: np.random.Generator) -> tuple[np.ndarray, list[str]]:
    names = ["water", "sand", "grass", "forest", "town", "road"]
    yy, xx = np.mgrid[0:H, 0:W]
    coast = 0.45 * W + wobble(rng, H, 10, 4)[:, None] + 6 * np.sin(yy / 9.0)
    m = np.zeros((H, W), np.uint8)  # water
    m[xx > coast - 2] = 1  # beach
    land = xx > coast + 2
    field = blobs(rng, (H, W), 5)
    m[land] = 2  # grass
    m[land & (field > 0.55)] = 3  # forest
    # A town on the shore, with a coast road behind the beach.
    m[land & ((yy - 0.6 * H) ** 2 / 14**2 + (xx - coast - 14) ** 2 / 9**2 < 1)] = 4
    m[np.abs(xx - coast - 6) < 0.75] = 5
    return m, names


def river_valley(rng: np.random.Generator) -> tuple[np.ndarray, list[str]]:
    names = ["forest", "crop field", "grass", "water", "rock", "road", "town"]
    yy, xx = np.mgrid[0:H, 0:W]
    centre = 0.5 * H + wobble(rng, W, 9, 6)[None, :] + 7 * np.sin(xx / 11.0)
    dist = np.abs(yy - centre)
    m = np.zeros((H, W), np.uint8)  # forest on the hillsides
    m[dist > 30 + 6 * blobs(rng, (H, W), 4)] = 4  # rocky ridges
    valley = dist < 17
    fields = blobs(rng, (H, W), 3)
    m[valley] = 1  # crop fields
    m[valley & (fields > 0.6)] = 2  # meadows
    m[dist < 1.6] = 3  # the river
    m[np.abs(yy - centre + 9) < 0.7] = 5  # valley road
    m[valley & ((xx - 0.3 * W) ** 2 + (yy - centre + 12) ** 2 < 30)] = 6  # village
    return m, names


def airfield(rng: np.random.Generator) -> tuple[np.ndarray, list[str]]:
    names = ["grass", "road", "town", "crop field", "forest", "sand"]
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    m = np.full((H, W), 3, np.uint8)  # farmland around
    m[blobs(rng, (H, W), 4) > 0.7] = 4  # woods
    # Airfield boundary (grass), a diagonal runway, a parallel taxiway, the apron and terminal.
    inside = (np.abs(xx - W / 2) < 40) & (np.abs(yy - H / 2) < 27)
    m[inside] = 0
    u = (xx - W / 2) * np.cos(0.35) + (yy - H / 2) * np.sin(0.35)
    v = -(xx - W / 2) * np.sin(0.35) + (yy - H / 2) * np.cos(0.35)
    m[inside & (np.abs(v) < 1.6) & (np.abs(u) < 38)] = 1  # runway
    m[inside & (np.abs(v - 7) < 0.7) & (np.abs(u) < 34)] = 1  # taxiway
    m[inside & (v > 8) & (v < 13) & (np.abs(u + 5) < 9)] = 1  # apron
    m[inside & (v >= 13) & (v < 19) & (np.abs(u + 5) < 8)] = 2  # terminal and hangars
    m[inside & (np.abs(v + 6) < 2.5) & (np.abs(u - 30) < 6)] = 5  # sandy overrun area
    m[(np.abs(yy - 0.9 * H) < 0.7)] = 1  # access road
    return m, names


MAPS = {"coastline": coastline, "river_valley": river_valley, "airfield": airfield}


def main() -> int:
    library = shipped_theme_library()
    listing = {}
    for k, (name, make) in enumerate(MAPS.items()):
        indices, names = make(np.random.default_rng(100 + k))
        themes = library.select(names)
        write_image(HERE / f"{name}.png", indices[:, :, None])
        project = project_from_index_image(
            indices, themes, CELL,
            {"created_by": "sample_maps/make_samples.py", "description": f"sample: {name}"},
        )
        save_project(HERE / f"{name}.ttproj", project)
        write_image(HERE / f"{name}_preview.png", render_project(project, scale=0.25))
        listing[name] = {"index_image": f"{name}.png", "project": f"{name}.ttproj",
                         "themes": names, "cell": list(CELL)}
        print(f"{name}: {W} x {H} vertices, themes {names}")
    text = json.dumps({"version": 1, "samples": listing}, indent=1) + "\n"
    write_bytes_atomic(HERE / "samples.json", text.encode())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
