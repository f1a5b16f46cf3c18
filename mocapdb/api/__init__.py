"""The Python API of a mocap database: one function per command of the CLI, same names.

Each function takes a connection from :func:`connect`, reads what it needs
from the database, calls the array functions of the algorithm sub-packages
and writes results back (sqlite-utils style). ``mocapdb COMMAND`` calls the
function of the same name with the same options (dashes for underscores).

=============================  ==========================
CLI                           API
=============================  ==========================
``mocapdb ingest``             :func:`ingest`
``mocapdb delete``             :func:`delete`
``mocapdb train``              :func:`train`
``mocapdb learn-keyframes``    :func:`learn_keyframes`
``mocapdb define-class``       :func:`define_class`
``mocapdb annotate``           :func:`annotate`
``mocapdb evaluate``           :func:`evaluate`
``mocapdb report``             :func:`report`
``mocapdb view``               :func:`view`
``mocapdb similar``            :func:`similar`
``mocapdb stats``              :func:`stats`
``mocapdb motions``            :func:`motions`
``mocapdb create-index``       :func:`create_index`
``mocapdb drop-index``         :func:`drop_index`
``mocapdb export-features``    :func:`export_features`
``mocapdb import-features``    :func:`import_features`
``mocapdb export-joints``      :func:`export_joints`
``mocapdb attach``             :func:`attach`
``mocapdb ray-annotate``       :func:`ray_annotate`
``mocapdb convert-labels``     :func:`convert_labels`
``mocapdb relocate``           :func:`relocate`
``mocapdb joint-map-template`` :func:`joint_map_template`
``mocapdb warmup``             :func:`warmup`
``mocapdb extension-path``     :func:`extension_path`
``mocapdb sql``                ``connect(...).sql(query)``
=============================  ==========================

``mocapdb serve`` is :func:`mocapdb.server.serve`: the web server is a face on
this API, as the command line is, so it sits above it and nothing here imports it.
"""
from mocapdb.api.database import (DeleteReport, attach, connect, convert_labels, create_index, delete, drop_index,
                                  export_features, export_joints, extension_path, import_features, ingest,
                                  joint_map_template, relocate)
from mocapdb.api.kernels import (background_compile_running, kernels_cold, start_background_compile,
                                 wait_for_background_compile, warmup)
from mocapdb.api.learning import define_class, learn_keyframes, train
from mocapdb.api.annotating import BATCH_FILES, BUCKET_MOTIONS, annotate, evaluate, ray_annotate
from mocapdb.api.outputs import FIGURES, SIMILAR_FORMATS, report, similar, stats, view
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.api.browsing import (MAX_LIMIT, MOTION_COLUMNS, SORTS, STRIP_BINS, label_colors, label_segments, labels,
                                  motion_info, motions)

#: exactly the commands: ``mocapdb COMMAND`` calls the function of that name (``sql`` is
#: ``connect(...).sql``); the other names here are what the command line needs besides
__all__ = ["connect", "ingest", "delete", "train", "learn_keyframes", "define_class", "annotate", "evaluate",
           "report", "view", "similar", "stats", "motions", "create_index", "drop_index", "export_features",
           "import_features", "export_joints", "attach", "ray_annotate", "convert_labels", "relocate",
           "joint_map_template", "warmup", "extension_path"]
