"""Blocks of strips: every strip formed on its own, then all transformed at once
onto the control and onto each other (:mod:`.strips`, R4 3)."""
