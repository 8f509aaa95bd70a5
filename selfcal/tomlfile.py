"""Reading a TOML file so that every failure is the caller's typed error.

``tomllib`` raises ``TOMLDecodeError`` for bad syntax, but a bare ``ValueError`` for an integer
of more than 4300 digits and ``RecursionError`` for arrays nested a thousand deep; reading the
file can raise ``UnicodeDecodeError`` or ``OSError``. :func:`read_toml` turns each into the
caller's :class:`~selfcal.errors.InputError` kind naming the file.
"""

from __future__ import annotations

import sys
from pathlib import Path

from selfcal.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["read_toml", "parse_toml"]


def parse_toml(
    text: str, where: str, error: type[InputError] = InputError, fix: str | None = None
) -> dict:
    """The TOML document ``text`` (from ``where``, a file name for messages).

    Raises:
        error: not valid TOML, a number TOML cannot hold, or nesting too deep.
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{where}: not a valid TOML file ({exc})", fix=fix) from None
    except (ValueError, RecursionError) as exc:  # 4300-digit integers, deep nesting
        raise error(f"{where}: not a valid TOML file ({str(exc)[:200]})", fix=fix) from None


def read_toml(
    path: str | Path,
    error: type[InputError] = InputError,
    fix: str | None = None,
    what: str = "file",
) -> dict:
    """The TOML document in the file ``path`` (UTF-8); ``what`` names the file in messages.

    Raises:
        error: missing or unreadable file, not UTF-8, or as :func:`parse_toml`.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{p}: no such {what}", fix=fix) from None
    except UnicodeDecodeError as exc:
        raise error(f"{p}: not a UTF-8 text file ({exc})", fix=fix) from None
    except OSError as exc:
        raise error(f"{p}: cannot read ({exc})", fix=fix) from None
    return parse_toml(text, str(p), error, fix)
