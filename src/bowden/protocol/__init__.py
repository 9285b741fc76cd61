"""Movement references and study design."""

from bowden.protocol.minimum_jerk import MinimumJerkCycle, minimum_jerk_position

__all__ = ["MinimumJerkCycle", "minimum_jerk_position"]
