"""lunarviz's own error type: bad input that the command line reports in one line (exit 2)."""


class LunarvizError(ValueError):
    """A user's input is invalid (a value, a file, a date). The message names the bad value.

    It subclasses ValueError so that callers catching ValueError keep working.
    """


class LunarvizWarning(UserWarning):
    """A result that is computed but may not mean what the user expects (e.g. a stale TLE)."""


class UnboundedRowsWarning(LunarvizWarning):
    """Rows of a run carry no error bound (their ``rtol`` is NaN; ``no_bound_reason`` says why)."""


class LooseRowsWarning(LunarvizWarning):
    """Rows of a run carry a bound above the tolerance (their ``rtol`` column) that the run could
    not foresee (a mapped Earth's, which depends on each row's own albedos and light)."""
