"""report --figure …: the paper's figures as PNG files with real content."""
from importlib import resources

import numpy as np
import pytest
from click.testing import CliRunner

import mocapdb
from mocapdb.cli import main

from conftest import DATA, run, write_truth_86_09, write_truth_86_09_eaf

pytestmark = pytest.mark.shared

CMU86_MAP = resources.files("mocapdb.shipped_models").joinpath("cmu86_labels.csv")


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    root = tmp_path_factory.mktemp("figures")
    path = root / "fig.duckdb"
    con = mocapdb.connect(path)
    mocapdb.ingest(con, [DATA / "cmu" / "86" / "86_09.amc"])
    con.close()
    return path, write_truth_86_09(root / "truth.csv")


def report(db_path, *args):
    return CliRunner().invoke(main, ["--db", str(db_path), "report", *map(str, args)], catch_exceptions=False)


def drawn(png):
    """The image as an (h, w, 3) float array, after checking it is a PNG with real content."""
    import matplotlib.image

    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = matplotlib.image.imread(png)[..., :3]
    ink = (img.min(axis=2) < 0.9).mean()  # share of pixels that are not (nearly) white
    colours = len(np.unique((img * 255).astype(np.uint8).reshape(-1, 3), axis=0))
    assert ink > 0.03 and colours > 30, (png.name, ink, colours)
    return img


@pytest.mark.slow
def test_delta_heat_map(db, tmp_path):
    path, truth = db
    out = tmp_path / "fig3.png"
    r = report(path, "--figure", "delta", "--motion", "86_09", "--truth", truth, "--label-map", CMU86_MAP, "--out", out)
    assert r.exit_code == 0, r.output
    img = drawn(out)
    # the heat map's jet colours: saturated blue where a class matches (move on the walks)
    assert ((img[..., 2] > 0.5) & (img[..., 0] < 0.2) & (img[..., 1] < 0.3)).sum() > 500


@pytest.mark.slow
def test_template_real_and_quantized(db, tmp_path):
    path, _ = db
    out = tmp_path / "fig1.png"
    r = report(path, "--figure", "template", "--class", "squat1Reps", "--out", out)
    assert r.exit_code == 0, r.output
    img = drawn(out)
    red = (img[..., 0] > 0.7) & (img[..., 1] < 0.3) & (img[..., 2] < 0.3)  # wildcards of the quantized MT
    assert red.sum() > 1000
    r = run(path, "report", "--figure", "template", "--out", out, code=1)
    assert "needs a class" in r.output and "squat1Reps" in r.output


def test_tau_sweep(db, tmp_path):
    path, truth = db
    out = tmp_path / "fig8.png"
    r = report(path, "--figure", "tau", "--truth", truth, "--label-map", CMU86_MAP, "--sweep-tau", "0.05:0.21:0.04",
               "--out", out)
    assert r.exit_code == 0, r.output
    img = drawn(out)
    green = (img[..., 1] > 0.4) & (img[..., 0] < 0.2) & (img[..., 2] < 0.2)  # the F-measure curves
    assert green.sum() > 100
    r = run(path, "report", "--figure", "tau", "--out", out, code=1)
    assert "needs ground truth" in r.output


@pytest.mark.slow
@pytest.mark.parametrize("figure", ["timeline", "annotation"])
def test_timeline_with_truth(db, tmp_path, figure):
    path, truth = db
    if figure == "timeline":  # the ground truth as an ELAN file
        truth = write_truth_86_09_eaf(tmp_path / "truth.eaf")
    out = tmp_path / f"{figure}.png"
    r = report(path, "--figure", figure, "--motion", "86_09", "--truth", truth, "--label-map", CMU86_MAP, "--out", out)
    assert r.exit_code == 0, r.output
    img = drawn(out)
    grey = (np.abs(img[..., 0] - 0.85) < 0.02) & (np.abs(img[..., 1] - 0.85) < 0.02)  # the truth bars
    assert grey.sum() > 1000


@pytest.mark.slow
def test_ga_curve(db, tmp_path):
    """Fig. 5 of a model whose keyframe queries the GA learned (the shipped default's are designed)."""
    from mocapdb.api import learn_keyframes, train

    path, _ = db
    with mocapdb.connect(path) as con:
        folder = tmp_path / "cut"                   # two real classes, symlinked (never copied)
        folder.mkdir()
        for f in [*(DATA / "hdm05_cut").glob("HDM_*.asf"), DATA / "hdm05_cut" / "squat1Reps",
                  DATA / "hdm05_cut" / "kickLFront1Reps"]:
            (folder / f.name).symlink_to(f, target_is_directory=f.is_dir())
        train(con, model="ga", folder=folder)
        learn_keyframes(con, model="ga", folder=folder, runs=2, generations=5, jobs=1)
    out = tmp_path / "fig5.png"
    assert report(path, "--figure", "ga", "--model", "ga", "--out", out).exit_code == 0
    drawn(out)
