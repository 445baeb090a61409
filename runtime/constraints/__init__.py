"""Constraint families: rows for the Lagrange-multiplier solver and projections for the procedural plan."""
