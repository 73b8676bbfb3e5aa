"""Time units: nanoseconds are the core's one unit of time; these say how many make the rest."""

NS_PER_US = 1_000
NS_PER_MS = 1_000_000
NS_PER_S = 1_000_000_000
