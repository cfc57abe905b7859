"""Issue 33, round four: inputs the earlier rounds did not reach, through the CLI.

Each case runs the CLI in a subprocess (:func:`test_hostile_round2.run`) and checks what
a user sees: exit status 2 and one error line, no input or unnamed file changed, no
stale or half-written output. This round covers the inputs of the tiled path's cluster
(TLS certificate files).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from terratheme.core.io.images import write_image
from test_hostile_round2 import refused, run


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> Path:
    """A folder with photo.png (24 x 24, three colours)."""
    folder = tmp_path_factory.mktemp("small")
    photo = np.zeros((24, 24, 3), np.uint8)
    photo[:12], photo[12:, :12], photo[12:, 12:] = (30, 80, 200), (40, 140, 40), (200, 190, 120)
    write_image(folder / "photo.png", photo)
    return folder


# -- certificate files that are no files -------------------------------------------------

@pytest.mark.parametrize("which", ["ca", "cert", "key"])
def test_a_tls_file_that_is_a_fifo_is_one_line_not_a_hang(small, tmp_path, which):
    """OpenSSL opened --tls-ca-file with no check: a named pipe there blocked convert
    --scheduler tls://... for ever (--tls-cert and --tls-key were opened the same way)."""
    files = {name: tmp_path / f"{name}.pem" for name in ("ca", "cert", "key")}
    for name, path in files.items():
        if name == which:
            os.mkfifo(path)
        else:
            path.write_text("not a certificate\n")
    proc = run("convert", small / "photo.png", tmp_path / "o.ttproj", "--tile", "16",
               "--scheduler", "tls://127.0.0.1:9", "--tls-ca-file", files["ca"],
               "--tls-cert", files["cert"], "--tls-key", files["key"], timeout=60)
    refused(proc, f"{files[which]}: ", "named pipe")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ca.pem", "cert.pem", "key.pem"]

