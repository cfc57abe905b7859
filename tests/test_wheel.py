"""The wheel: built from the working tree, installed into a fresh venv, run from another folder.

The venv has no system site-packages and no terratheme but the wheel's; it
borrows the test venv's installed dependencies through a ``.pth`` line (a
path only: the editable install's finder there is not loaded), so the test
runs offline. After ``python -m terratheme.app.warmup`` the commands must
compile no numba kernel (the caches land in the venv's own site-packages).
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
SOURCES = ("pyproject.toml", "README.md", "core", "app", "themes", "models", "sample_maps")
PHOTO = REPO / "sample_maps" / "dubai_marina.jpg"
DATA = ("terratheme/core/gpu/shaders/tt_terrain.frag.glsl",
        "terratheme/core/exchange/scripts/TerrathemeImporter.cs",
        "terratheme/core/exchange/scripts/TerrathemeTerrain.shader",
        "terratheme/core/exchange/scripts/TerrathemeColourMap.cginc",
        "terratheme/themes/themes.json", "terratheme/themes/looks.json",
        "terratheme/themes/sand.png", "terratheme/models/models.json",
        "terratheme/models/aerial.model", "terratheme/sample_maps/airfield.ttproj")


def _setuptools_version() -> tuple[int, ...]:
    if importlib.util.find_spec("setuptools") is None:
        return (0,)
    from importlib.metadata import version

    return tuple(int(p) for p in version("setuptools").split(".")[:1])


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    if _setuptools_version() < (77,):
        pytest.skip("building offline needs setuptools>=77 in the venv (bash setup.sh --test)")
    src = tmp_path_factory.mktemp("src")
    junk = shutil.ignore_patterns("__pycache__", "*.egg-info", "build", "*.pyc")
    for name in SOURCES:
        if (REPO / name).is_dir():
            shutil.copytree(REPO / name, src / name, ignore=junk)
        else:
            shutil.copy2(REPO / name, src / name)
    dist = tmp_path_factory.mktemp("dist")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                    "--no-build-isolation", "--no-index", "-w", str(dist), str(src)],
                   check=True, capture_output=True)
    (whl,) = dist.glob("terratheme-*.whl")
    return whl


@pytest.fixture(scope="module")
def env(wheel, tmp_path_factory) -> dict:
    """A fresh venv holding the wheel; its interpreter, script folder and site-packages."""
    root = tmp_path_factory.mktemp("venv")
    venv.EnvBuilder(with_pip=False, symlinks=True).create(root)
    python = root / "bin" / "python"
    purelib = Path(subprocess.run([str(python), "-c", "import sysconfig; print("
                                   "sysconfig.get_paths()['purelib'])"],
                                  check=True, capture_output=True, text=True).stdout.strip())
    (purelib / "_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q",
                    "--no-deps", "--no-index", str(wheel)], check=True, capture_output=True)
    run_env = {k: v for k, v in os.environ.items()
               if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH", "PYTHONDONTWRITEBYTECODE")}
    run_env["QT_QPA_PLATFORM"] = "offscreen"
    return {"python": python, "bin": root / "bin", "purelib": purelib, "env": run_env,
            "cwd": tmp_path_factory.mktemp("elsewhere")}


def _run(env: dict, *args: str, timeout: float = 600) -> str:
    result = subprocess.run([str(env["bin"] / "terratheme"), *args], cwd=env["cwd"],
                            env=env["env"], capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, (args, result.stdout, result.stderr)
    return result.stdout


def _caches(env: dict) -> set[Path]:
    return set(env["purelib"].rglob("*.nbi"))


@pytest.fixture(scope="module")
def converted(env) -> Path:
    """The sample photo converted with the shipped model, after the warm-up."""
    subprocess.run([str(env["python"]), "-m", "terratheme.app.warmup"], cwd=env["cwd"],
                   env=env["env"], check=True, capture_output=True, timeout=1800)
    env["warm"] = _caches(env)
    _run(env, "convert", str(PHOTO), "out/photo.ttproj", "--model", "aerial")
    return env["cwd"] / "out" / "photo.ttproj"


def test_the_wheel_installs_under_the_project_name_only(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names} == {"terratheme", "terratheme-0.1.0.dist-info"}
    # Every module of core/ and app/ (a package missing from pyproject's list is lost).
    for part in ("core", "app"):
        for path in (REPO / part).rglob("*.py"):
            assert f"terratheme/{path.relative_to(REPO).as_posix()}" in names, path
    for name in DATA:
        assert name in names


def test_installed_commands_run_from_another_folder(env, converted):
    site = env["purelib"]
    assert not (site / "core").exists() and not (site / "app").exists()
    out = _run(env, "themes")
    assert f"9 themes in {site / 'terratheme' / 'themes'}" in out
    assert "'name': 'building'" in _run(env, "info", str(converted))  # the shipped model's
    for suffix in ("_preview.png", "_colour.avif"):
        assert (converted.parent / f"photo{suffix}").is_file()
    _run(env, "render", str(converted), "out/cpu.png")
    _run(env, "export", str(converted), "out/unity", "--engine", "unity")
    assert (env["cwd"] / "out/unity/Editor/TerrathemeImporter.cs").is_file()
    # The editor without a project opens the shipped sample, from the installed package.
    sample = subprocess.run([str(env["python"]), "-c", "from terratheme.app.editor.newproject "
                             "import sample_project_path; print(sample_project_path())"],
                            env=env["env"], cwd=env["cwd"], capture_output=True, text=True)
    assert sample.stdout.strip() == str(site / "terratheme" / "sample_maps" / "airfield.ttproj")
    if importlib.util.find_spec("PySide6") is not None:
        _run(env, "app", "--screenshot", "out/editor.png")
        assert (env["cwd"] / "out/editor.png").stat().st_size > 0
    # The warm-up's kernels were cached in the venv and served every command above.
    assert env["warm"] and _caches(env) == env["warm"]


def test_installed_gpu_render_matches_the_cpu(env, converted, gl_ctx):
    from terratheme.core.io.images import read_image

    _run(env, "render", str(converted), "out/gpu.png", "--gpu")
    _run(env, "render", str(converted), "out/cpu2.png")
    gpu, cpu = (read_image(env["cwd"] / "out" / n) for n in ("gpu.png", "cpu2.png"))
    assert gpu.shape == cpu.shape and (gpu == cpu).all()
    assert _caches(env) == env["warm"]
