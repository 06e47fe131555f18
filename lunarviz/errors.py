"""lunarviz's own error type: bad input that the command line reports in one line (exit 2)."""

import difflib
import re


#: how messages name options: ``--time-range`` on the command line (set by it while it runs), the
#: Python keyword ``time_range`` for the API
_WORDS = {"command_line": False}
_FLAG = re.compile(r"(?<![\w-])--(no-)?([a-z][a-z0-9]*(?:-[a-z0-9]+)*)")


class LunarvizError(ValueError):
    """A user's input is invalid (a value, a file, a date). The message names the bad value, and
    the option in the caller's words: the flag on the command line, the keyword in Python.

    It subclasses ValueError so that callers catching ValueError keep working.
    """

    def __str__(self) -> str:
        return in_callers_words(super().__str__())


def in_callers_words(text: str) -> str:
    """``text`` naming options as the caller does: flags on the command line, keywords in Python."""
    return text if _WORDS["command_line"] else _FLAG.sub(_keyword, text)


#: flags whose keyword is not the flag's own words (``--band``: ``bands``), registered by the
#: option schema (:mod:`lunarviz.options`)
FLAG_KEYWORDS: dict[str, str] = {}


def _keyword(m: re.Match) -> str:
    """A flag's API keyword: ``--band`` → ``bands``, ``--no-occlusion`` → ``occlusion=False``."""
    flag = f"--{m.group(1) or ''}{m.group(2)}"
    name = FLAG_KEYWORDS.get(flag)
    if name is not None:
        return name if not m.group(1) else f"{name}=False"
    return m.group(2).replace("-", "_") + ("=False" if m.group(1) else "")


class command_line_words:
    """While active (the command line's run), errors name options by their flags."""

    def __enter__(self):
        self._was = _WORDS["command_line"]
        _WORDS["command_line"] = True

    def __exit__(self, *exc):
        _WORDS["command_line"] = self._was


class LunarvizWarning(UserWarning):
    """A result that is computed but may not mean what the user expects (e.g. a stale TLE); it
    names options in the caller's words, as :class:`LunarvizError` does."""

    def __str__(self) -> str:
        return in_callers_words(super().__str__())


class ZonelessTimeWarning(LunarvizWarning):
    """A time was given without a zone (``2026-01-15T03:00``) and is taken as UTC."""


class UnboundedRowsWarning(LunarvizWarning):
    """Rows of a run carry no error bound (their ``rtol`` is NaN; ``no_bound_reason`` says why)."""


class ApparentAlbedoWarning(LunarvizWarning):
    """Rows' apparent albedo p* lies outside 0-1, which no Lambert sphere gives (its p* is its
    albedo at every phase): the Earth's phase law is not Lambert's there, or the ratio is
    ill-conditioned (near full Moon the earthlit Moon is a thin, faint crescent)."""


class LooseRowsWarning(LunarvizWarning):
    """Rows of a run carry a bound above the tolerance (their ``rtol`` column) that the run could
    not foresee (a mapped Earth's, which depends on each row's own albedos and light)."""


class UnpolarisedRowsWarning(LunarvizWarning):
    """Rows of a ``--stokes`` run carry no polarisation (NaN Stokes fields): their phase angle or
    wavelengths lie outside the Moon's polarisation model."""


def any_case(value, choices) -> str | None:
    """The choice ``value`` names, exactly or in another case (``DHG``: ``dhg``), where one does."""
    if value in choices:
        return value
    same = [c for c in choices if isinstance(c, str) and isinstance(value, str) and c.lower() == value.lower()]
    return same[0] if len(same) == 1 else None


def short_repr(value, size: int = 40) -> str:
    """``repr(value)`` on one line, at most ``size`` characters (an integer of 400 digits, an array)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= size else text[:size - 3] + "..."


def close_match(value, choices) -> str | None:
    """The choice a misspelt ``value`` most likely meant (case ignored), or None."""
    names = [str(c) for c in choices]
    low = {n.lower(): n for n in names}
    hit = difflib.get_close_matches(str(value).lower(), list(low), n=1, cutoff=0.6)
    return low[hit[0]] if hit else None


def did_you_mean(value, choices) -> str:
    """`` (did you mean 'x'?)`` for a misspelt ``value``, or an empty string."""
    hit = close_match(value, choices)
    return f" (did you mean {hit!r}?)" if hit is not None and hit != value else ""


def unknown_choice(what: str, value, choices) -> LunarvizError:
    """The one-line error for a ``value`` of ``what`` that is not one of ``choices``: the choices,
    and the close match a misspelling most likely meant."""
    return LunarvizError(f"unknown {what} {value!r}{did_you_mean(value, choices)}: choose from "
                         f"{', '.join(str(c) for c in choices)}")
