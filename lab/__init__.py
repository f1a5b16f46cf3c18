"""The development lab: how mocapdb's default model is made and measured (not installed).

Beside ``benchmarks/``, outside the package, as scikit-learn keeps its benchmark
and dataset code out of ``sklearn``: a user's ``pip install`` carries the
measures (:mod:`mocapdb.evaluation`), not the harness. Nothing under
``mocapdb/`` imports this folder (tests/test_style.py); the tests and the
benchmarks put the repository root at the end of ``sys.path`` to reach it.

- :mod:`lab.documents`, :mod:`lab.development`: the development documents and
  folds (leave-one-actor-out, CMU, leave-one-lab-out) and their scores;
- :mod:`lab.studio`, :mod:`lab.lab_clips`: other labs' clips scored by what
  a user expects of each; :mod:`lab.calibration`: whether confidence says right;
- :mod:`lab.records`: the quality guard's headline figures and records;
- :mod:`lab.turns`, :mod:`lab.retrieval`: the turn and query-by-example evaluations;
- :mod:`lab.recipe`, :mod:`lab.cutting`, :mod:`lab.thresholds`,
  :mod:`lab.generalisation`, :mod:`lab.robust_queries`, :mod:`lab.default_model`:
  the default model's recipe and training (``benchmarks/train_default_model.py``);
- :mod:`lab.amass_write`: AMASS-format fixtures written from ASF/AMC takes.
"""
