"""How much an observation said for "a body that moves": the Bayes factor between two values of a track's
P(a body that moves), independent of where it started (a person born of a leg pair starts at its legs'
leg probability, one born of a lone leg at even odds: vipsm.people._born_dynamic)."""

from __future__ import annotations


def bayes_factor(before: float, after: float) -> float:
    """The likelihood ratio that took a probability from ``before`` to ``after`` (odds after / odds before)."""
    return (after / (1.0 - after)) / (before / (1.0 - before))
