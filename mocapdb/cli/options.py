"""The options several commands share (one definition each, one help text)."""
from __future__ import annotations

import functools
from pathlib import Path

import click

from mocapdb.errors import os_error_text


FORMATS = ("table", "csv", "json")


def make_parent(ctx, param, value):
    """The callback of every option naming a file to write (``--out``, ``--report``): its folder is made,
    as a user writing ``--out results/x.eaf`` means; a folder that cannot be made is a usage error naming
    why (never Python's ``[Errno …]``)."""
    if value is not None:
        folder = Path(value).parent
        blocker = next((p for p in (folder, *folder.parents) if p.exists() and not p.is_dir()), None)
        if blocker is not None:
            raise click.BadParameter(f"cannot make its folder: {blocker} is a file", ctx, param)
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise click.BadParameter(f"cannot make its folder ({os_error_text(exc)})", ctx, param) from None
    return value


def model_option(help="Model name (default: the shipped default model)."):
    return click.option("--model", default="default", show_default=True, help=help)


tau_option = click.option("--tau", type=float,
                          help="Hit threshold τ for every class (default: each class's; paper 0.13).")


keyframes_option = click.option("--keyframes/--no-keyframes", default=None,
                                help="Keyframe preselection (default: on when the model has keyframe "
                                     "queries; --no-keyframes is the toolbox's reference mode).")


silent_option = click.option("--silent", is_flag=True, help="No progress bar.")


min_length_option = click.option("--min-length/--no-min-length", default=None,
                                 help="Drop segments shorter than their label's minimum (default: on; models "
                                      "without minimums, as the toolbox's, keep every segment).")


min_won_option = click.option("--min-won/--no-min-won", default=None,
                              help="Drop segments whose label is the best label on fewer than a third of its "
                                   "minimum length (default: on; no effect on models without minimums).")


margin_option = click.option("--margin", type=float,
                             help="Leave frames unlabelled where the best label wins by less than this "
                                  "(default: the model's margin, 0 for the shipped models = off, as the paper).")


#: the units a BVH source may be given in (export-joints --unit): mocapdb.bodies.units.UNITS' names, which the
#: API checks (the CLI imports only mocapdb.api; tests/test_units.py holds the two equal)
UNIT_NAMES = ("m", "cm", "mm", "inch", "cmu")


format_option = click.option("--format", "fmt", type=click.Choice(FORMATS), default="table", show_default=True)


folder_option = click.option("--folder", type=click.Path(exists=True, file_okay=False, path_type=Path),
                             help="Clips in the HDM05 cut layout: one folder per class (files read directly).")


labels_option = click.option("--labels", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                             help="Label file document,label,start_frame,end_frame (native frames, 1-based) "
                                  "or ELAN .eaf file cutting clips out of ingested documents.")


truth_help = ("Ground truth: a CSV document,label,start_frame,end_frame[,fps] (native frames, 1-based, unless an fps "
              "column gives their rate; `annotate --format csv` output reads back as it is) or an ELAN .eaf file "
              "(each annotation's value is the label; the document is the linked media file's stem). Other "
              "formats: `mocapdb convert-labels`.")


map_option = click.option("--label-map", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                          help="CSV class,label renaming truth labels to model labels (e.g. walk -> move).")


#: the options of how files are read, as the API's keywords (the fields of mocapdb.readers.ReaderOptions)
READER_KEYWORDS = ("asf", "joint_map", "marker_map", "marker_rules", "body_model", "max_decompressed")


def reader_options(fn):
    """``--asf``, ``--joint-map``, ``--marker-map``, ``--marker-rules``, ``--body-model`` and
    ``--max-decompressed``: how files are read, one set of options for ``ingest`` and ``ray-annotate``
    (so both read a file alike). The command gets them as one value, ``reader`` (a dict of the API's
    keywords), and passes it on whole: ``api.ingest(…, **reader)``. A new reader option is one more
    option here and one more name in :data:`READER_KEYWORDS`."""

    @functools.wraps(fn)
    def command(*args, **kwargs):
        reader = {name: kwargs.pop(name) for name in READER_KEYWORDS}
        return fn(*args, reader=reader, **kwargs)

    command = click.option("--max-decompressed", metavar="SIZE", default=None,
                           help="The bytes a compressed file or zip member may decompress to (e.g. 2GiB); a "
                                "file over it fails, the others go in (default: MOCAPDB_MAX_DECOMPRESSED, else "
                                "512MiB).")(command)
    command = click.option("--body-model", type=click.Path(exists=True, path_type=Path),
                           help="AMASS .npz files: the SMPL-H/SMPL-X body model .npz you downloaded, or a folder "
                                "of them (chosen by family and gender, e.g. smplh/female/model.npz), giving each "
                                "take's own rest joints (default: a generic rest skeleton shipped with "
                                "mocapdb).")(command)
    command = click.option("--marker-rules", type=click.Choice(("toolbox", "anatomical")), default=None,
                           help="C3D files of the HDM05/CMU marker set: the toolbox's formulas (default, the "
                                "reference) or anatomical joint centres (closer to the same take's AMC).")(command)
    command = click.option("--marker-map", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                           help="TOML/JSON file: canonical joint = the C3D markers whose mean it is.")(command)
    command = click.option("--joint-map", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                           help="TOML/JSON file: canonical joint = the BVH joint (its origin), \"Joint/end\" (its "
                                "End Site) or a list of joints (their mean); overrides the automatic mapping of "
                                "every BVH file.")(command)
    return click.option("--asf", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                        help="Skeleton for every AMC file (default: found by the dataset conventions: "
                             "same-stem .asf, the CMU subject's NN.asf, HDM05's HDM_<actor>.asf).")(command)


def annotation_options(fn):
    """``--model``, ``--tau``, ``--keyframes``, ``--min-length``, ``--min-won`` and ``--margin``: how
    motions are annotated (annotate, evaluate: one set of options, one help text)."""
    for option in (margin_option, min_won_option, min_length_option, keyframes_option, tau_option, model_option()):
        fn = option(fn)
    return fn
