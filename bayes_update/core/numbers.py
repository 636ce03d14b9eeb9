"""Numbers printed with the digits their uncertainty resolves.

A value known to +- sd is printed to the decimal place of the second
significant digit of sd (:data:`SD_DIGITS`), the sd itself with two
significant digits: 25.0312 +- 0.0043 prints as ``25.0312 +- 0.0043``,
1234.5 +- 210 as ``1230 +- 210``, so that an interval whose ends differ is
never printed as "25 - 25".  Very large or very small values go to
scientific notation with the same resolution (``1.2345e+07``).  Without a
usable sd (zero, negative, NaN) a value gets six significant digits.
"""

from __future__ import annotations

import math

__all__ = ["SD_DIGITS", "decimals_for", "format_sd", "format_value"]

#: significant digits of the sd that the printed values resolve
SD_DIGITS = 2


def decimals_for(sd: float, digits: int = SD_DIGITS) -> int | None:
    """Decimal places that show ``digits`` significant digits of ``sd`` (negative:
    round to tens, hundreds, ...); None without a usable sd."""
    try:
        sd = float(sd)
    except (TypeError, ValueError):
        return None
    if not (math.isfinite(sd) and sd > 0):
        return None
    return digits - 1 - math.floor(math.log10(sd))


def format_value(value: float, sd: float, digits: int = SD_DIGITS) -> str:
    """``value`` to the decimal place that ``sd`` resolves (module docstring)."""
    value = float(value)
    if not math.isfinite(value):
        return str(value)
    d = decimals_for(sd, digits)
    if d is None:
        return f"{value:.6g}"
    if value != 0 and (abs(value) >= 1e6 or abs(value) < 1e-4):
        mantissa = max(math.floor(math.log10(abs(value))) + d, 0)
        return f"{value:.{mantissa}e}"
    if d <= 0:
        return f"{round(value, d) + 0.0:.0f}"
    return f"{value:.{d}f}"


def format_sd(sd: float, digits: int = SD_DIGITS) -> str:
    """The sd itself, with ``digits`` significant digits."""
    try:
        sd = float(sd)
    except (TypeError, ValueError):
        return str(sd)
    if not math.isfinite(sd) or sd <= 0:
        return f"{sd:.6g}"
    return format_value(sd, sd, digits)
