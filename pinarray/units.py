"""Time units: nanoseconds are the core's one unit of time; these say how many make the rest."""

NS_PER_US = 1_000
NS_PER_MS = 1_000_000
NS_PER_S = 1_000_000_000


def duration_words(seconds: float) -> str:
    """A duration as people say it, to two units: ``45 s``, ``3 min 20 s``, ``11 h 7 min``,
    ``2 days 3 h``, ``about 300 years`` (an estimate of work, not a measurement)."""
    if not seconds < 100 * 365 * 86400:  # NaN and infinity too
        return "centuries"
    whole = round(seconds)
    if whole < 60:
        return f"{max(whole, 1) if seconds > 0 else 0} s"
    for unit, size, smaller, size_smaller in (("days", 86400, "h", 3600), ("h", 3600, "min", 60),
                                              ("min", 60, "s", 1)):
        if whole >= size:
            big, rest = divmod(whole, size)
            small = rest // size_smaller
            name = "day" if unit == "days" and big == 1 else unit
            return f"{big} {name}" + (f" {small} {smaller}" if small else "")
    raise AssertionError(seconds)
