"""Text a code block produced, made safe for consoles, markdown, recordings and prompts.

- `clean(text)`: every C0 and C1 control character (newline and tab excepted), DEL, and the
  bidirectional overrides and isolates written as visible escapes (`\\x1b`, `\\u202e`), so
  no terminal sequence (clear screen, OSC 52 clipboard, OSC 8 links) or reordering survives.
- `quoted(text)`: the block's own text shown inside a parent-made sentence: cleaned, on
  one line, in double quotes, cut to a length.
- `name_problem(name)`: why an object name is refused (names are NFKC-normalized letters,
  digits, spaces and basic punctuation with no invisible characters), or None.
- `fence(text)`: a backtick fence longer than any run of backticks in `text`.

Standard library only.
"""

from __future__ import annotations

import re
import unicodedata

_BIDI = "\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069"
_UNSAFE = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f" + _BIDI + "]")
#: Punctuation an object name may use besides letters, digits and the space.
NAME_PUNCTUATION = frozenset("-_.,:;'\"()/#&+!?%")
#: Letters that show as nothing: Hangul fillers (Lo), and combining grapheme joiners.
_INVISIBLE_LETTERS = frozenset("\u115f\u1160\u3164\uffa0\u034f\u17b4\u17b5")


def _escape(match: re.Match[str]) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code <= 0xFF else f"\\u{code:04x}"


def clean(text: str) -> str:
    """`text` with its control characters escaped (see the module docstring)."""
    return _UNSAFE.sub(_escape, text)


def quoted(text: str, limit: int = 300) -> str:
    """`text` cleaned, on one line, double-quoted, at most `limit` characters inside."""
    one_line = clean(text).replace("\n", "\\n").replace("\t", " ").replace('"', "'")
    if len(one_line) > limit:
        one_line = one_line[:limit] + "..."
    return f'"{one_line}"'


def name_problem(name: str) -> str | None:
    """Why `name` cannot name an object, or None if it can."""
    if unicodedata.normalize("NFKC", name) != name:
        return "it changes under Unicode NFKC normalization (write it in plain characters)"
    for char in name:
        if char in _INVISIBLE_LETTERS:
            return f"it holds an invisible character (U+{ord(char):04X})"
        if char == " " or char in NAME_PUNCTUATION:
            continue
        if unicodedata.category(char)[0] not in "LN":
            return (f"it holds {_shown(char)}; names are letters, digits, spaces and "
                    f"the punctuation {''.join(sorted(NAME_PUNCTUATION))}")
    if not name.strip():
        return "it is blank"
    return None


def _shown(char: str) -> str:
    if char.isprintable() and not char.isspace():
        return f"{char!r} (U+{ord(char):04X})"
    return f"the invisible character U+{ord(char):04X}"


def fence(text: str, marker: str = "`") -> str:
    """A fence of `marker` at least three long and longer than any run of it in `text`."""
    longest = max((len(run) for run in re.findall(re.escape(marker) + "+", text)), default=0)
    return marker * max(3, longest + 1)
