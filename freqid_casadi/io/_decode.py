"""The text of a file's bytes: UTF-8, UTF-16 with a byte-order mark, the encoding the
file declares, else Windows-1252 or Latin-1 as analysers on Windows write (layer L1)."""

import codecs
import re
import warnings

from ._readfile import DataWarning
from ..errors import DataError

__all__ = ["decode_text"]

_DECLARED = re.compile(rb"(?:encoding|charset|code[ _-]?page)\s*[:=]?\s*[\"']?"
                       rb"([A-Za-z][A-Za-z0-9_.:-]{1,30})", re.IGNORECASE)


def _declared(payload):
    """The codec a file's first lines declare (``encoding: latin-1``, ``charset=cp1252``,
    ``Codepage: 1252``), as a Python codec name, or None."""
    m = _DECLARED.search(payload[:4096])
    if m is None:
        return None
    name = m.group(1).decode("ascii").rstrip(".:;-")
    name = f"cp{name}" if name.isdigit() else name
    try:
        return codecs.lookup(name).name
    except LookupError:
        return None


def _utf16(payload):
    """Text of a UTF-16 file with a byte-order mark, or None when the bytes do not read as
    mostly ASCII text that way (binary data that happens to start with 0xfffe)."""
    if not payload.startswith((b"\xff\xfe", b"\xfe\xff")) or len(payload) % 2:
        return None
    try:
        text = payload.decode("utf-16")
    except UnicodeDecodeError:
        return None
    ascii_share = sum(ch.isascii() for ch in text) / max(len(text), 1)
    return text if text and ascii_share > 0.9 and "\x00" not in text else None


def decode_text(path, payload):
    """The text of a file's bytes ``payload``.

    UTF-8 first (a leading byte-order mark dropped); UTF-16 with a byte-order mark; else
    the encoding the file declares in its first lines (``encoding: ...``), else
    Windows-1252 (or Latin-1 where Windows-1252 leaves a byte undefined), as analysers on
    Windows write (``m/s\u00b2`` in a unit line). A fallback is stated by a
    :class:`~freqid_casadi.io._readfile.DataWarning` naming the first byte that is not
    UTF-8.

    Parameters
    ----------
    path : str
        The file, for messages.
    payload : bytes

    Returns
    -------
    str

    Raises
    ------
    DataError
        NUL bytes (binary data, not text).
    """
    text = _utf16(payload)
    if text is not None:
        return text[1:] if text.startswith("\ufeff") else text
    if b"\x00" in payload:
        raise DataError(f"{path!r} is not a text CSV file (not UTF-8): it holds NUL bytes "
                        "(binary data); export the data as UTF-8 text")
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError as exc:
        text = _fallback(path, payload, exc)
    return text[1:] if text.startswith("\ufeff") else text


def _fallback(path, payload, exc):
    line = payload[:exc.start].count(b"\n") + 1
    declared = _declared(payload)
    tried = [c for c in (declared, "cp1252", "latin-1") if c]
    for codec in tried:
        try:
            text = payload.decode(codec)
        except (UnicodeDecodeError, LookupError):
            continue
        shown = {"cp1252": "Windows-1252", "latin-1": "Latin-1",
                 "iso8859-1": "Latin-1"}.get(codec, codec)
        warnings.warn(f"{path!r} is not UTF-8 (byte 0x{payload[exc.start]:02x} on line "
                      f"{line}): read as {shown}"
                      f"{' (as it declares)' if codec == declared else ''}; save it as UTF-8 "
                      "to silence this note", DataWarning, stacklevel=4)
        return text
    raise DataError(f"{path!r} is not UTF-8 text (byte 0x{payload[exc.start]:02x} on line "
                    f"{line}); save the file as UTF-8 text")          # latin-1 never fails
