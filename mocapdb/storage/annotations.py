"""Annotating stored motions (with the stored keyframe index) and storing the results.

:func:`annotate_documents` is the one annotation path of the database: the
Python API (``mocapdb.api.annotate``, ``evaluate``) and the SQL function
``annotate()`` both call it, with models and the index from the connection's
:class:`~mocapdb.storage.cache.ConnectionCache`.
"""
from __future__ import annotations

import numpy as np

from mocapdb.annotation import annotate, annotate_sweep, uses_keyframes
from mocapdb.storage.cache import UNKNOWN
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction


def stored_preselection(cache, key, model, motion_ids, lengths, *, keyframes=None, index_version=UNKNOWN):
    """The ``preselection`` for stored motions: from the stored index when the model preselects, else None."""
    if not uses_keyframes(model, keyframes):
        return None
    return cache.preselection(key, model, motion_ids, lengths, version=index_version)


def annotate_documents(cache, key, model, words, lengths, motion_ids, *, tau=None, keyframes=None,
                       index_version=UNKNOWN, taus=None, min_length=None, margin=None):
    """Segments of stored motions (0-based inclusive, ``doc`` indexing ``motion_ids``).

    Parameters
    ----------
    cache : ConnectionCache
    key, model
        From :meth:`ConnectionCache.model`.
    words : (N,) uint64
        The motions' words, concatenated in the order of ``motion_ids``.
    lengths : (n,) int
    motion_ids : (n,) int
    tau : float, optional
        One hit threshold for every class (default: each class's τ).
    keyframes : bool, optional
        Keyframe preselection (default: when the model has keyframe queries).
    taus : sequence of float, optional
        Annotate once per τ instead (paper Fig. 8): returns a list.
    min_length, margin : optional
        The segment filters (:func:`mocapdb.annotation.annotate`; default the model's).

    Returns
    -------
    ndarray of SEGMENT_DTYPE, or a list of them with ``taus``
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    pre = stored_preselection(cache, key, model, motion_ids, lengths, keyframes=keyframes,
                              index_version=index_version)
    if taus is not None:
        return annotate_sweep(words, model, taus, doc_lengths=lengths, preselection=pre, min_length=min_length,
                              margin=margin)
    return annotate(words, model, doc_lengths=lengths, preselection=pre, tau=tau, keep_hits=False,
                    min_length=min_length, margin=margin).segments


def store_annotations(con, table, motion_ids, *, model, tau, keyframes) -> None:
    """Replace the stored annotations of ``motion_ids`` under ``model`` (one transaction).

    ``table`` has the columns of :data:`mocapdb.annotation.SEGMENT_COLUMNS`.
    """
    with transaction(con):
        con.execute(statement("annotations.sql", "delete"), {"model": model, "ids": [int(i) for i in motion_ids]})
        with registered(con, mocap_new_annotations=table):
            con.execute(statement("annotations.sql", "insert"), {"model": model, "tau": tau, "keyframes": keyframes})


__all__ = ["annotate_documents", "stored_preselection", "store_annotations"]
