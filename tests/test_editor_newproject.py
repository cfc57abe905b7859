"""A new editor project over a photo of any channel layout (app.editor.newproject)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_a_new_project_over_a_grey_or_alpha_photo(tmp_path, channels):
    from terratheme.app.editor.newproject import project_from_photo
    from terratheme.core.io.images import write_image

    photo = np.zeros((40, 56, channels), np.uint8)
    photo[..., 0] = np.arange(56, dtype=np.uint8)[None, :] * 4
    if channels in (2, 4):
        photo[..., -1] = 255
    write_image(tmp_path / "p.png", photo)
    project = project_from_photo(tmp_path / "p.png")
    assert project.photo.shape == (40, 56, 3)
    np.testing.assert_array_equal(project.photo[..., 0], photo[..., 0])
