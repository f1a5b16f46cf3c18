"""Exceptions raised by mocapdb. Every error derives from :class:`MocapdbError`."""
import math
import re

#: a message's words longer than this are cut (a name can be megabytes long)
LONG_WORD = 200
#: a message longer than this keeps its start and end
LONG_MESSAGE = 4000

_LONG_WORD = re.compile(r"\S{%d,}" % (LONG_WORD + 1))


def shorten(value, limit=80) -> str:
    """``repr`` of a value for a message, cut to ``limit`` characters with its length said.

    A name can be megabytes long (a hostile archive, a pasted file): a message
    echoes its start and its length, never all of it.
    """
    s = str(value)
    if len(s) <= limit:
        return repr(s)
    return repr(s[:limit]) + f"… ({len(s):,} characters)"


def clip_message(text) -> str:
    """A message with every word longer than :data:`LONG_WORD` characters cut (its length said)
    and, beyond :data:`LONG_MESSAGE` characters, its middle left out."""
    # the word's end (a closing quote, a semicolon) is kept: the message stays readable
    s = _LONG_WORD.sub(lambda m: f"{m.group(0)[:80]}…({len(m.group(0)):,} characters)…{m.group(0)[-4:]}", str(text))
    if len(s) > LONG_MESSAGE:
        s = s[:LONG_MESSAGE - 1000] + f" … ({len(s) - LONG_MESSAGE + 1000:,} characters left out) … " + s[-1000:]
    return s


#: control characters (C0, DEL, C1): a message quoting a binary file's bytes or a file name
#: must not send them raw to a terminal or a log
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def escape_control(text: str) -> str:
    """``text`` with control characters written as ``\\xNN`` (tab and line feed kept)."""
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", text)


def os_error_text(exc: OSError) -> str:
    """An ``OSError`` as ``path: reason`` (``No such file or directory``), never Python's
    ``[Errno 2] …`` form; the second path of a rename or link too."""
    reason = exc.strerror or (str(exc.args[-1]) if exc.args else type(exc).__name__)
    names = [str(n) for n in (exc.filename, exc.filename2) if n is not None]
    return escape_control(clip_message(f"{' → '.join(names)}: {reason}" if names else reason))


class MocapdbError(Exception):
    """Root of all mocapdb errors. A message is clipped (:func:`clip_message`): values echoed in
    it, however long, never make it longer than a few thousand characters."""

    def __init__(self, *args):
        if args and isinstance(args[0], str):
            args = (clip_message(args[0]), *args[1:])
        super().__init__(*args)


class ParameterError(MocapdbError, ValueError):
    """A parameter value is invalid; the message names the parameter and the fix."""


class ParseError(MocapdbError, ValueError):
    """A motion file is malformed.

    The message starts with ``path:line`` (and the frame or joint where it
    applies) followed by what was expected and what was found, e.g.
    ``walk.bvh:1207 (frame 88): expected 57 channels, got 54``.
    """

    def __init__(self, path, line, message, *, frame=None):
        self.path = str(path)
        self.line = None if line is None else int(line)  # int(): readers may pass a lazily counted line
        line = self.line
        self.frame = frame
        where = f"{self.path}:{line}" if line is not None else self.path
        if frame is not None:
            where += f" (frame {frame})"
        # what a reader quotes of a broken file may hold any byte: never raw control characters
        super().__init__(escape_control(f"{where}: {message}"))
        self.reason = clip_message(escape_control(message))


class SchemaError(MocapdbError):
    """The database lacks an object (table, motion, model, class) that a call needs."""


class PartialAnnotationError(MocapdbError):
    """Some motions could not be annotated; the others were (and, when asked, stored).

    Attributes
    ----------
    failed : list of (motion_id, name, reason)
    table : pyarrow.Table
        The segments of the motions that were annotated.
    """

    def __init__(self, failed, table, n_motions, stored):
        self.failed, self.table = list(failed), table
        done = n_motions - len(self.failed)
        more = f" (and {len(self.failed) - 1} more)" if len(self.failed) > 1 else ""
        super().__init__(f"{len(self.failed)} of {n_motions} motions not annotated, the other {done} "
                         f"{'annotated and stored' if stored else 'annotated'}: {self.failed[0][2]}{more}")


def check_nonnegative(value, name, *, none="") -> float | None:
    """``value`` as a non-negative finite float: the one check of τ, margins and the like.

    Parameters
    ----------
    value
        A number (not a bool); None only when ``none`` says what None means.
    name : str
        The parameter, for the message.
    none : str
        What None stands for (e.g. "each class's τ"); empty: None is refused.

    Raises
    ------
    ParameterError
        "NAME must be a non-negative number[ or None (...)], got VALUE".
    """
    if value is None and none:
        return None
    if (isinstance(value, bool) or not isinstance(value, (int, float)) and not _is_numpy_number(value)
            or not math.isfinite(value) or value < 0):
        also = f" or None ({none})" if none else ""
        raise ParameterError(f"{name} must be a non-negative number{also}, got {value!r}")
    return float(value)


def _is_numpy_number(value) -> bool:
    # errors is the bottom layer: numpy scalars are recognised without importing numpy
    return type(value).__module__ == "numpy" and hasattr(value, "dtype") and value.dtype.kind in "iuf"


__all__ = ["MocapdbError", "ParameterError", "ParseError", "SchemaError", "PartialAnnotationError",
           "check_nonnegative", "shorten", "clip_message", "escape_control", "os_error_text"]
