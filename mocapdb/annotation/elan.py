"""ELAN annotation files (``.eaf``): labelled segments in and out, through pympi-ling.

ELAN (https://archive.mpi.nl/tla/elan) is the tool annotators of human
movement work in; an ``.eaf`` file is accepted wherever a label CSV is
(:func:`mocapdb.annotation.read_labels` dispatches on the suffix).

Written files (:func:`write_eaf`): one document per file, the source
recording as linked media (``MEDIA_URL`` absolute ``file://`` URL, plus the
path relative to the ``.eaf``), one time-aligned tier per label (segments of
different labels may overlap, which annotations on one ELAN tier may not),
each annotation's value the label, times in milliseconds, and the
document's native frame rate as the header property ``mocapdb:source_fps``.

Read files (:func:`read_eaf`), the tier → label rule:

* every annotation of every time-aligned tier is a segment; its **value** is
  the label (whitespace stripped); an empty value takes the **tier name**.
  Tier names are otherwise ignored; reference (symbolic) tiers are skipped,
  as are annotations whose time slots have no time (ELAN's unaligned slots;
  logged). An annotation that refers to a time slot the file does not
  define is an error naming it;
* the **document** is the stem of the first linked media file (its URL
  %-decoded; format and compression suffixes dropped, ``walk%2001.bvh.gz`` →
  ``walk 01``), else the stem of the ``.eaf`` file itself (motion names are
  file stems);
* times → native frames at the document's rate ``fps`` (the database's
  ``motions.source_fps`` when the caller knows it, else the file's
  ``mocapdb:source_fps`` property): native frame k (1-based) spans
  [(k − 1)/fps, k/fps), so an annotation [t0, t1) ms covers the frames
  round(t0·fps/1000) + 1 … round(t1·fps/1000) (at least one frame).
  Segments written by :func:`write_eaf` come back on exactly their frames.
"""
from __future__ import annotations

import logging
import os
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pympi  # pympi-ling, a runtime dependency (3 ms to import)

from mocapdb.errors import ParameterError, ParseError
from mocapdb.readers.sources import motion_stem

log = logging.getLogger("mocapdb")

__all__ = ["EAF_FPS_PROPERTY", "CONFIDENCE_TIER", "eaf_document", "eaf_source_fps", "read_eaf", "write_eaf",
           "is_eaf"]

#: header property holding the document's native frame rate (Hz)
EAF_FPS_PROPERTY = "mocapdb:source_fps"


def is_eaf(path) -> bool:
    """Whether ``path`` names an ELAN file (by its suffix, ``.eaf``)."""
    return isinstance(path, (str, Path)) and Path(path).suffix.lower() == ".eaf"


def _open(path):
    p = Path(path)
    if not p.is_file():
        raise ParseError(path, None, "cannot read the ELAN file: no such file")
    try:
        return pympi.Elan.Eaf(str(p))
    except Exception as exc:  # pympi raises XML parse errors of several types
        raise ParseError(path, None, f"not a readable ELAN file ({type(exc).__name__}: {exc})") from exc


def _document(eaf, path):
    for media in eaf.media_descriptors:
        url = media.get("MEDIA_URL") or media.get("RELATIVE_MEDIA_URL")
        if url:
            # a URL: its path %-decoded (a space, unicode); a motion name is the stem without the format
            # and compression suffixes (walk 01.bvh.gz -> walk 01), as ingest names it
            stem = motion_stem(unquote(urlsplit(url).path if "://" in url else url).rstrip("/"))
            if stem:
                return stem
    return Path(path).stem


def eaf_document(path) -> str:
    """The document an ELAN file annotates: its first linked media file's stem, else its own stem.

    Raises
    ------
    ParseError
        If the file cannot be read as ELAN.
    """
    return _document(_open(path), path)


def _property_rate(eaf, path):
    prop = dict(eaf.properties).get(EAF_FPS_PROPERTY) if eaf.properties else None
    try:
        return float(prop) if prop is not None else None
    except ValueError:
        raise ParseError(path, None, f"property {EAF_FPS_PROPERTY} must be a number, got {prop!r}") from None


def eaf_source_fps(path):
    """The native frame rate an ELAN file states (its ``mocapdb:source_fps`` property), or None.

    Raises
    ------
    ParseError
        If the file cannot be read as ELAN or the property is not a number.
    """
    return _property_rate(_open(path), path)


def read_eaf(path, *, fps=None):
    """The labelled segments of an ELAN file, on the document's native frames.

    Parameters
    ----------
    path : str or Path
    fps : float or mapping of str to float, optional
        Native frame rate of the document (a mapping: document → rate, as a
        database knows it). Default: the file's ``mocapdb:source_fps``
        property.

    Returns
    -------
    list of (document, label, start, end)
        Native frames, 1-based inclusive, in tier order then time order.

    Raises
    ------
    ParseError
        If the file is not ELAN, an annotation refers to a time slot the file
        does not define or ends before it starts, or no frame rate is known
        for the document.
    """
    eaf = _open(path)
    doc = _document(eaf, path)
    rate = fps.get(doc) if isinstance(fps, dict) else fps
    if rate is None:
        rate = _property_rate(eaf, path)
    if rate is None:
        raise ParseError(path, None, f"ELAN times are in ms and the frame rate of document {doc!r} is unknown: "
                         "ingest the document (the database knows its rate) or add the header property "
                         f"{EAF_FPS_PROPERTY}")
    if not (np.isfinite(rate) and rate > 0):
        raise ParseError(path, None, f"the frame rate of document {doc!r} must be positive, got {rate!r}")
    out = []
    for tier in eaf.get_tier_names():
        aligned = eaf.tiers[tier][0]
        if not aligned:  # a reference tier: its annotations have no times of their own
            continue
        for ann_id, (ts0, ts1, value, _) in sorted(aligned.items(), key=lambda kv: (
                eaf.timeslots.get(kv[1][0]) is None, eaf.timeslots.get(kv[1][0]) or 0)):
            missing = [ts for ts in (ts0, ts1) if ts not in eaf.timeslots]
            if missing:
                raise ParseError(path, None, f"annotation {ann_id} on tier {tier!r} refers to the time slot "
                                 f"{missing[0]!r}, which the file's TIME_ORDER does not define")
            t0, t1 = eaf.timeslots[ts0], eaf.timeslots[ts1]
            if t0 is None or t1 is None:  # an unaligned slot: ELAN interpolates it for display only
                log.warning("%s: annotation %s on tier %r has a time slot without a time; skipped",
                            path, ann_id, tier)
                continue
            if t1 <= t0:
                raise ParseError(path, None, f"annotation {ann_id} on tier {tier!r} ends ({t1} ms) at or before "
                                 f"it starts ({t0} ms)")
            label = (value or "").strip() or tier
            start = int(round(t0 * rate / 1000.0)) + 1
            end = max(start, int(round(t1 * rate / 1000.0)))
            out.append((doc, label, start, end))
    return out


#: MIME types of linked media that ELAN plays, by suffix
_MIME = {".mp4": "video/mp4"}

#: suffix of the tier that holds a label tier's confidences (a symbolic association: readers skip it)
CONFIDENCE_TIER = " confidence"


def write_eaf(path, labels, start_s, end_s, *, media=None, fps=None, author="mocapdb", confidence=None):
    """Write one document's labelled segments as an ELAN file (one tier per label).

    Parameters
    ----------
    path : str or Path
    labels : sequence of str, length n
    start_s, end_s : (n,) float
        Segment start and end in seconds (end exclusive, as ``annotate``'s
        ``start_s`` / ``end_s``); written as whole milliseconds.
    media : str or Path, or a sequence of them, optional
        The recording, linked as the file's media (absolute ``file://`` URL
        and the path relative to ``path``); with more files, each is linked
        in order (the first names the document when the file is read back),
        an ``.mp4`` as ``video/mp4``, which ELAN plays (``annotate --video``).
    fps : float, optional
        Native frame rate of the recording, stored as the header property
        ``mocapdb:source_fps`` so the file reads back without a database.
    author : str
    confidence : (n,) float, optional
        Each segment's confidence (0–1), written on a dependent tier
        ``"<label> confidence"`` (symbolic association, ELAN shows it under
        its label; :func:`read_eaf` skips such tiers, so the file reads back
        onto the same segments).

    Raises
    ------
    ParameterError
        If the lengths differ or a segment ends before it starts.
    """
    labels = [str(x) for x in labels]
    t0 = np.rint(np.asarray(start_s, np.float64) * 1000.0).astype(np.int64)
    t1 = np.rint(np.asarray(end_s, np.float64) * 1000.0).astype(np.int64)
    if not (len(labels) == t0.size == t1.size):
        raise ParameterError(f"labels, start_s and end_s must have the same length, got "
                             f"{len(labels)}, {t0.size}, {t1.size}")
    if (t0 < 0).any() or (t1 <= t0).any():
        raise ParameterError("segments must satisfy 0 <= start_s < end_s")
    eaf = pympi.Elan.Eaf(author=author)
    eaf.remove_tier("default")
    for item in [] if media is None else [media] if isinstance(media, (str, os.PathLike)) else media:
        item = Path(item).resolve()
        try:
            rel = os.path.relpath(item, Path(path).resolve().parent)
        except ValueError:  # another drive on Windows
            rel = None
        # ELAN's MIME type for a file it cannot play (a recording is not audio or video), or a video it plays
        eaf.add_linked_file(item.as_uri(), relpath=rel, mimetype=_MIME.get(item.suffix.lower(), "unknown"))
    if fps is not None:
        eaf.add_property(EAF_FPS_PROPERTY, repr(float(fps)))
    for lab in dict.fromkeys(labels):
        eaf.add_tier(lab)
    for lab, a, b in zip(labels, t0.tolist(), t1.tolist()):
        eaf.add_annotation(lab, a, b, lab)
    if confidence is not None:
        conf = np.asarray(confidence, dtype=np.float64)
        if conf.size != len(labels):
            raise ParameterError(f"confidence must have one value per segment ({len(labels)}), got {conf.size}")
        eaf.add_linguistic_type("confidence", constraints="Symbolic_Association", timealignable=False)
        for lab in dict.fromkeys(labels):
            eaf.add_tier(lab + CONFIDENCE_TIER, ling="confidence", parent=lab)
        for lab, a, b, q in zip(labels, t0.tolist(), t1.tolist(), conf.tolist()):
            eaf.add_ref_annotation(lab + CONFIDENCE_TIER, lab, (a + b) // 2, f"{q:.3f}")
    pympi.Elan.to_eaf(str(path), eaf, pretty=True)
