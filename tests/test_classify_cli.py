"""``terratheme classify`` end to end on small files."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.io.images import read_image, read_labels, write_image


@pytest.fixture()
def photo(tmp_path):
    img = np.empty((64, 96, 3), np.uint8)
    img[:, :48] = (40, 120, 40)
    img[:, 48:] = (190, 170, 140)
    truth = np.full((64, 96), 2, np.uint8)
    truth[:, 48:] = 7
    write_image(tmp_path / "photo.png", img)
    scribbles = np.zeros_like(truth)
    scribbles[30, 10:30] = 2
    scribbles[30, 60:80] = 7
    write_image(tmp_path / "scribbles.png", scribbles)
    write_image(tmp_path / "truth.png", truth)
    return tmp_path, truth


def test_unsupervised_writes_a_palette_label_image(photo, capsys):
    d, truth = photo
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "labels.png"),
                 "--confidence", str(d / "conf.png")]) == 0
    labels = read_labels(d / "labels.png")
    assert labels.shape == (64, 96) and labels.dtype == np.uint8
    assert set(np.unique(labels)) == {1, 2}
    assert (labels[:, :40] != labels[:, 56:][:, :40]).all()
    # Shown in colour: classes 1 and 2 in the first two shipped themes' colours (sand, town).
    shown = read_image(d / "labels.png")
    assert shown.shape == (64, 96, 3)
    assert {tuple(shown[labels == 1][0]), tuple(shown[labels == 2][0])} == {
        (225, 200, 140), (200, 60, 60)}
    conf = read_image(d / "conf.png")
    assert conf.shape == (64, 96, 1) and conf.dtype == np.uint8 and conf.max() == 255
    assert "2 classes" in capsys.readouterr().out


def test_running_out_of_memory_at_the_summary_writes_nothing(photo, capsys, monkeypatch):
    # The class shares were counted after the outputs were committed: an error there left
    # them written under an "error" exit.
    d, _ = photo
    real = np.bincount

    def short(values, *args, **kwargs):
        if np.asarray(values).size == 64 * 96:
            raise MemoryError
        return real(values, *args, **kwargs)

    monkeypatch.setattr(np, "bincount", short)
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "labels.png"),
                 "--confidence", str(d / "conf.png")]) == 2
    assert "not enough memory" in capsys.readouterr().err
    assert not (d / "labels.png").exists() and not (d / "conf.png").exists()


def test_themes_option(photo):
    d, _ = photo
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "l.png"), "--themes", "1"]) == 0
    assert (read_labels(d / "l.png") == 1).all()


def test_scribbles_model_out_and_model(photo):
    d, truth = photo
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "a.png"),
                 "--scribbles", str(d / "scribbles.png"), "--model-out", str(d / "m.ttc"),
                 "--confidence", str(d / "conf.tif")]) == 0
    a = read_labels(d / "a.png")
    assert (a[:, :40] == 2).all() and (a[:, 56:] == 7).all()
    conf = read_image(d / "conf.tif")
    assert conf.dtype == np.float32 and 0.0 <= conf.min() and conf.max() <= 1.0
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "b.png"),
                 "--model", str(d / "m.ttc")]) == 0
    np.testing.assert_array_equal(read_labels(d / "b.png"), a)


def test_train_pairs(photo):
    d, truth = photo
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "c.png"),
                 "--train", str(d / "photo.png"), str(d / "truth.png")]) == 0
    assert (read_labels(d / "c.png") == truth).mean() > 0.95


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--scribbles", "{d}/small.png"], "must have the photo's size"),
        (["--model", "{d}/none.ttc", "--scribbles", "{d}/scribbles.png"], "do not combine"),
        (["--themes", "3", "--scribbles", "{d}/scribbles.png"], "--themes is for unsupervised"),
        (["--model-out", "{d}/m.ttc"], "needs training data"),
        (["--model", "{d}/none.ttc"], "no such model"),
        (["--scribbles", "{d}/rgb.png"], "single-channel"),
    ],
)
def test_user_errors_exit_2_with_one_line(photo, capsys, extra, match):
    d, _ = photo
    write_image(d / "small.png", np.zeros((10, 10), np.uint8))
    rgb = np.zeros((64, 96, 3), np.uint8)
    rgb[..., 0] = 1
    write_image(d / "rgb.png", rgb)
    args = [a.format(d=d) for a in extra]
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "x.png"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0]
    assert not (d / "x.png").exists()


def test_position_trains_a_placed_model(photo):
    d, truth = photo
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "p.png"), "--position",
                 "--scribbles", str(d / "scribbles.png"), "--model-out", str(d / "p.ttc")]) == 0
    assert (read_labels(d / "p.png") == truth).mean() > 0.95
    from terratheme.core.classify import Classifier

    assert Classifier.load(d / "p.ttc").options.features.position


@pytest.mark.parametrize("extra", [[], ["--scribbles", "{d}/scribbles.png",
                                        "--train", "{d}/photo.png", "{d}/truth.png"]])
def test_position_needs_scribbles_alone(photo, capsys, extra):
    d, _ = photo
    args = [a.format(d=d) for a in extra]
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "x.png"), "--position",
                 *args]) == 2
    assert "--position needs --scribbles and no --train" in capsys.readouterr().err
    assert not (d / "x.png").exists()


def test_outputs_are_written_as_one_set(photo, monkeypatch, capsys):
    # A failure writing the last output (the model) leaves none of them, nor temporaries.
    from terratheme.core.classify.supervised import Classifier
    from terratheme.core.errors import TerrathemeError

    d, _ = photo
    before = sorted(p.name for p in d.iterdir())

    def fail(self, path):
        raise TerrathemeError(f"{path}: disk full")

    monkeypatch.setattr(Classifier, "save", fail)
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "a.png"),
                 "--scribbles", str(d / "scribbles.png"), "--model-out", str(d / "m.ttc"),
                 "--confidence", str(d / "conf.png")]) == 2
    assert "disk full" in capsys.readouterr().err
    assert sorted(p.name for p in d.iterdir()) == before
