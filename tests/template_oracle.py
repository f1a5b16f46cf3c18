"""Loaders for the toolbox oracle of templates, Δ and annotation (tests only).

Oracle files are 1-based and features-first (40 × K); everything returned
here is frames-first and ready for the numpy-level API.
"""
import csv
from functools import lru_cache

import numpy as np

from conftest import ORACLE
from mocapdb.features import pack_words
from mocapdb.annotation.model import ClassModel, Model
from mocapdb.templates import QuantizedTemplate

TEMPLATES = ORACLE / "templates"
ANNOTATION = ORACLE / "annotation"
SQUAT = ORACLE / "template_squat1Reps"
DOCS = ("86_09", "02_01", "02_03", "02_04", "02_06")
#: coarse labels of the oracle annotation, in its field order (oracle README)
COARSE = {
    "move": ("sneak2StepsLStart", "jogLeftCircle4StepsRstart"),
    "sitLieDown": ("lieDownFloor",),
    "jump": ("hopBothLegs1hops",),
    "kick": ("kickLFront1Reps",),
    "rotateArms": ("rotateArmsBothBackward1Reps",),
    "throwR": ("throwBasketball",),
    "grabDepR": ("grabHighR", "depositFloorR"),
    "exercise": ("elbowToKnee1RepsLelbowStart", "squat1Reps"),
}
CLASSES = tuple(sorted(c for cs in COARSE.values() for c in cs))


@lru_cache(maxsize=None)
def features(stem):
    """(n, 40) bool 30 Hz features of an oracle feature file."""
    x = np.loadtxt(ORACLE / "features" / f"{stem}_feat30.csv", delimiter=",", skiprows=1,
                   ndmin=2)
    return x.astype(bool)


def words(stem):
    return pack_words(features(stem))


def csv_matrix(path):
    """A numeric CSV (no header) as float64, ``Inf`` parsed."""
    return np.loadtxt(path, delimiter=",", ndmin=2)


def csv_table(path):
    """(header, float64 rows) of a CSV with a header row."""
    with open(path) as fh:
        header = fh.readline().strip().split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def csv_rows(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


def training_clips(cls):
    return [s.strip() for s in (TEMPLATES / cls / "training_clips.txt").read_text().split()
            if s.strip()]


def stats(path):
    """template_stats.txt as {key: list of str}."""
    out = {}
    for line in path.read_text().splitlines():
        parts = line.split()
        if parts:
            out[parts[0]] = parts[1:]
    return out


def real_template(folder):
    """(real (K, 40), weights (K,)) of an oracle template folder."""
    return (csv_matrix(folder / "template_real.csv").T,
            csv_matrix(folder / "template_weights.csv").ravel())


def quantized_template(folder):
    return QuantizedTemplate.from_dense(
        csv_matrix(folder / "template_quantized_0.05.csv").T,
        csv_matrix(folder / "template_quantized_weights.csv").ravel())


@lru_cache(maxsize=None)
def oracle_model():
    """The 11 oracle classes (alphabetical, as the oracle's columns) with coarse labels."""
    label = {c: lab for lab, cs in COARSE.items() for c in cs}
    classes = [ClassModel(c, label[c], quantized=quantized_template(TEMPLATES / c))
               for c in CLASSES]
    return Model("oracle", classes, labels=tuple(COARSE))
