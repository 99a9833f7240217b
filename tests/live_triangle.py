"""The live tests' scenario: three holonomic robots holding a fixed triangle (a team file's text)."""


def triangle(duration: float = 2.0) -> str:
    """The scenario file's text, ``duration`` s long."""
    return f"""
kind = "team"
name = "live-triangle"
title = "Three holonomic robots holding a triangle"
source = "tests"
duration_s = {duration!r}
dt_s = 0.02
metrics_from_s = 0.0

[[robots]]
model = "holonomic"
count = 3

[shape]
template = "ring"
radius = 1.0

[path]
kind = "fixed"
center = [0.0, 0.0, 1.0]

[safety]
min_separation_m = 0.3
"""
