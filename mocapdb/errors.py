"""Exceptions raised by mocapdb. Every error derives from :class:`MocapdbError`."""
import re

#: control characters (C0, DEL, C1): a message quoting a binary file's bytes or a file name
#: must not send them raw to a terminal or a log
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def escape_control(text: str) -> str:
    """``text`` with control characters written as ``\\xNN`` (tab and line feed kept)."""
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", text)


class MocapdbError(Exception):
    """Root of all mocapdb errors."""


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
        self.reason = escape_control(message)


class SchemaError(MocapdbError):
    """The database lacks an object (table, motion, model, class) that a call needs."""


__all__ = ["MocapdbError", "ParameterError", "ParseError", "SchemaError", "escape_control"]
