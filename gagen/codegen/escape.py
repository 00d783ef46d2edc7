"""The escaping filters of the templates: one per context a label can reach (a C comment, a C string, a
Python docstring or comment, a Python string). Every label (docs, joint names, the source's file name)
goes into generated code only through one of them; names go in only as checked identifiers."""

from __future__ import annotations


def _escape_char(ch: str) -> str:
    code = ord(ch)
    named = {"\n": "\\n", "\t": "\\t", "\r": "\\r"}
    if ch in named:
        return named[ch]
    if code < 0x100:
        return f"\\x{code:02x}"
    return f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def c_comment(text: object) -> str:
    """``text`` inside a C block comment, on one line: printable ASCII stays, except ``*`` (so no
    ``*/`` or ``/*`` can form), ``?`` (trigraphs such as ``??/``) and ``\\`` (line splices), which
    are written as escapes like every control and non-ASCII character (``\\x2a``, ``\\u00e9``)."""
    return "".join(ch if " " <= ch <= "~" and ch not in "*?\\" else _escape_char(ch) for ch in str(text))


def c_string(text: object) -> str:
    """``text`` as the inside of a C string literal: ``"``, ``\\`` and ``?`` escaped, every byte of
    anything but printable ASCII as an octal escape (three digits: never merges with what follows)."""
    out = []
    for byte in str(text).encode():
        ch = chr(byte)
        out.append("\\" + ch if ch in '"\\?' else ch if 0x20 <= byte < 0x7F else f"\\{byte:03o}")
    return "".join(out)


def py_doc(text: object) -> str:
    """``text`` inside a (non-raw) triple-quoted Python docstring or a comment, on one line: ``"`` and
    ``\\`` escaped (no ``\"\"\"`` can close it), control and non-ASCII characters as escapes."""
    return "".join(ch if " " <= ch <= "~" and ch not in '"\\' else
                   "\\" + ch if ch in '"\\' else _escape_char(ch) for ch in str(text))


def py_string(text: object) -> str:
    """``text`` as a complete Python string literal (quotes included), ASCII only."""
    return ascii(str(text))


FILTERS = {"c_comment": c_comment, "c_string": c_string, "py_doc": py_doc, "py_string": py_string}
