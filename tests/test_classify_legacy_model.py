"""Model files of terratheme 0.x (OpenCV forests) are refused by their version, unread.

Regression for issue 33: a ``forest.yml`` of a few bytes of OpenCV YAML with a
``!!binary`` block made OpenCV's parser spin for good (Ctrl-C ignored), and a
crafted version-1 forest of 524k nodes took 90 s to load. The OpenCV reader is
gone: such a file is one line naming the unsupported format version, exit 2.
"""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from terratheme.core.classify import Classifier, train_classifier
from terratheme.core.errors import UnsupportedVersionError
from terratheme.core.io.images import write_image

#: OpenCV YAML whose empty base64 header made cv2.FileStorage loop forever
SPINNING_YAML = b"%YAML:1.0\n---\na: !!binary |\n  ICAgICAgICAgICAgICAgICAgICAgICAg\n"


@pytest.fixture(scope="module")
def meta(tmp_path_factory):
    """meta.json of a small trained model, as a dict."""
    photo = np.zeros((32, 32, 3), np.uint8)
    photo[:, 16:] = (200, 180, 150)
    mask = np.zeros((32, 32), np.uint8)
    mask[8, 2:10], mask[8, 20:30] = 1, 2
    path = tmp_path_factory.mktemp("m") / "m.model"
    train_classifier([(photo, mask)]).save(path)
    with zipfile.ZipFile(path) as zf:
        return json.loads(zf.read("meta.json"))


def _legacy(path, meta, version, forest_yml):
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("meta.json", json.dumps(dict(meta, version=version)))
        zf.writestr("forest.yml", forest_yml)
    return path


@pytest.mark.parametrize("version", [1, 2])
@pytest.mark.parametrize("forest_yml", [SPINNING_YAML, b"%YAML:1.0\n---\n" + b"x" * 524288])
def test_an_opencv_forest_file_is_an_unsupported_version(tmp_path, meta, version, forest_yml):
    path = _legacy(tmp_path / "old.model", meta, version, forest_yml)
    with pytest.raises(UnsupportedVersionError,
                       match=f"unsupported model format version {version} .*terratheme 0.x"):
        Classifier.load(path)


def test_the_cli_says_one_line_and_exits_2(tmp_path, meta):
    # A subprocess: the old reader never returned (the timeout only guards the suite).
    photo = tmp_path / "photo.png"
    write_image(photo, np.full((16, 16, 3), 90, np.uint8))
    model = _legacy(tmp_path / "old.model", meta, 2, SPINNING_YAML)
    run = subprocess.run([sys.executable, "-m", "terratheme.app.cli", "classify", str(photo),
                          "-o", str(tmp_path / "labels.png"), "--model", str(model)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "unsupported model format version 2" in lines[0]
    assert not (tmp_path / "labels.png").exists()
