"""The case loader's one error: a one-line message naming the file and the key path."""

from __future__ import annotations

import re

MAX_MESSAGE = 280  # characters of a CaseError's text (the CLI adds "pulseform: error: ")
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def one_line(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text`` as one printable line of at most ``limit`` characters.

    Control characters (newlines, NUL, ...) and unencodable ones (lone surrogates) are escaped; a
    longer text keeps its start and end around `` … ``.
    """
    text = _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), text)
    text = text.encode("utf-8", "backslashreplace").decode("utf-8")
    if len(text) > limit:
        head = (limit - 3) * 2 // 3
        text = text[:head] + " … " + text[len(text) - (limit - 3 - head):]
    return text


class CaseError(ValueError):
    """A case file or an override is invalid. ``str()`` is one line naming file and key path.

    The line is at most :data:`MAX_MESSAGE` characters: a long source, key or message is elided in
    the middle, control characters are escaped.
    """

    def __init__(self, source: str, path: str, message: str) -> None:
        self.source = source
        self.path = path
        self.message = message
        src, key = one_line(source, 120), one_line(path, 100)
        where = f"{src}: {key}: " if path else f"{src}: "
        super().__init__(where + one_line(message, MAX_MESSAGE - len(where)))
