"""Shared pieces of the random tasks of the property tests."""

from __future__ import annotations


def region_atoms(n: int, m: int, k: int) -> list[str]:
    """The propositions r<i>_p<k> and o<j>_p<k> of n robots, m objects and k regions."""
    return [f"r{i}_p{p}" for i in range(1, n + 1) for p in range(1, k + 1)] + \
        [f"o{j}_p{p}" for j in range(1, m + 1) for p in range(1, k + 1)]
