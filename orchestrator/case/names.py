"""The names of a case file that become file or folder names, and their rules (one home for both).

Two kinds of name:

- **the case name** (``case.name``) names a folder, ``results/<name>`` (and ``<name>_sweep``, ``<name>_converge``,
  ``<name>_compare``), and prefixes the field files ``fields/<name>_<body>.xdmf``. It may be written in the
  user's own language (``Blechumformung Prüfstand``, ``名前``): :func:`folder_name` normalises it to Unicode NFC
  (macOS keyboards and file systems may hand over decomposed letters, ``e`` + U+0301; one spelling makes one
  folder) and :func:`check_folder_name` accepts letters of any script (with their combining marks), decimal
  digits of any script, spaces and ``. _ -``, at most :data:`MAX_NAME_BYTES` bytes in UTF-8. Refused: every other
  character (the path separators ``/`` ``\\``, the characters Windows and macOS refuse in a file name
  ``< > : " | ? *``, control, format and invisible characters such as U+202E or U+200B, other spaces such as
  U+00A0, symbols and emoji), a leading space, ``.`` or ``-`` (a hidden folder, an option to a shell command), a
  trailing space or ``.`` (Windows drops them: two names, one folder), and the device names Windows reserves
  (``CON``, ``PRN``, ``AUX``, ``NUL``, ``COM1``–``COM9``, ``LPT1``–``LPT9``, alone or before a ``.``).
- **identifiers** (body, probe and source names; :func:`check_file_name`) stay ASCII letters, digits and
  ``. _ -``: they are also history.csv column prefixes, metric names (``<body>_max_speed_m_s``) and parts of a
  ``--set`` path (``bodies.<name>.mesh_size``).

The byte limit keeps every file a run writes under the 255-byte limit of a file name:
``fields/<case>_<body>_part<k>.xdmf`` is at most 100 + 1 + 100 + 12 bytes.
"""

from __future__ import annotations

import re
import unicodedata

from .schema import SchemaError, shorten

__all__ = ["MAX_NAME_BYTES", "FOLDER_NAME_CHARACTERS", "folder_name", "check_folder_name", "check_file_name"]

#: most bytes (UTF-8) of a case name: 100 ASCII characters, 50 of most European or Cyrillic letters with
#: diacritics, 33 CJK characters
MAX_NAME_BYTES = 100
#: the characters a case name may hold, as the error messages and the docs say them
FOLDER_NAME_CHARACTERS = "letters of any script, digits, spaces, '.', '_', '-'"
_PUNCTUATION = frozenset(" ._-")
_RESERVED = re.compile(r"(CON|PRN|AUX|NUL|COM[1-9]|LPT[1-9])(\..*)?", re.IGNORECASE)
_IDENTIFIER = re.compile(r"[A-Za-z0-9._-]{1,100}")


def folder_name(name: str) -> str:
    """``name`` in Unicode normal form C (composed letters: ``e`` + U+0301 becomes ``é``)."""
    return unicodedata.normalize("NFC", name)


def _allowed(c: str) -> bool:
    """A letter (L*), a combining mark (M*: the vowel signs of Devanagari, Thai, ...), a decimal digit (Nd) of any
    script, or one of ``' ' . _ -``."""
    return c in _PUNCTUATION or unicodedata.category(c)[0] in "LM" or unicodedata.category(c) == "Nd"


def check_folder_name(name: str, path: str, names: str) -> None:
    """Refuse a case name that is no portable folder name (the rules: the module docstring).

    Parameters
    ----------
    name : str
        The name, NFC-normalised (:func:`folder_name`).
    path : str
        Its key, e.g. ``case.name``.
    names : str
        What it names, for the message (``results/<name>``).

    Raises
    ------
    SchemaError
        One line naming the rule that failed and the characters allowed.
    """
    shown = shorten(repr(name))
    why = f"it names the folder {names}"
    if not name:
        raise SchemaError(path, f"got an empty string; must be 1 to {MAX_NAME_BYTES} bytes of {FOLDER_NAME_CHARACTERS}")
    size = len(name.encode("utf-8"))
    if size > MAX_NAME_BYTES:
        raise SchemaError(path, f"got {shown} ({size} bytes in UTF-8); at most {MAX_NAME_BYTES} bytes "
                          f"({MAX_NAME_BYTES} ASCII characters, 33 CJK ones; {why})")
    bad = next((c for c in name if not _allowed(c)), None)
    if bad is not None:
        raise SchemaError(path, f"got {shown}: {bad!r} (U+{ord(bad):04X}) is not allowed; allowed: "
                          f"{FOLDER_NAME_CHARACTERS} ({why})")
    if name[0] in " .-" or name[-1] in " ." or unicodedata.category(name[0])[0] == "M":
        raise SchemaError(path, f"got {shown}; must not start with a space, '.', '-' or a combining mark, nor end "
                          f"with a space or '.' ({why}; allowed: {FOLDER_NAME_CHARACTERS})")
    if _RESERVED.fullmatch(name):
        raise SchemaError(path, f"got {shown}; a device name Windows reserves (CON, PRN, AUX, NUL, COM1-9, LPT1-9, "
                          f"also before a '.'), not a folder name ({why})")


def check_file_name(name: str, path: str, names: str) -> None:
    """An identifier that becomes part of a file name, a history column and a ``--set`` path (body, probe and
    source names): 1 to 100 ASCII letters, digits, ``.``, ``_`` or ``-``, not ``.`` or ``..``; never a path."""
    if not _IDENTIFIER.fullmatch(name) or name in (".", ".."):
        raise SchemaError(path, f"got {shorten(repr(name))}; must be a name, not a path: 1 to 100 ASCII letters, "
                          f"digits, '.', '_' or '-', not '.' or '..' (it names {names})")
