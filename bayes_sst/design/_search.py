"""Greedy search of the next tests on the Fisher (linearised-alpha Laplace) approximation.

At each step every candidate is tried on top of the tests already chosen and the one that
lowers the design loss most is taken (a candidate may be chosen again: repeating the most
informative test is a legitimate answer once between-test variation dominates):

    loss = sum_k max(log(w_k/target_k), 0) + EPSILON * sum_k log(w_k/target_k)

w_k the predicted relative half-width of target parameter k. The first sum drives every
unmet target down; the small second one keeps shrinking all targets once they are met,
so the order of the list stays meaningful past the point where the targets are reached.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from bayes_sst.design._engine import PARAMETERS, DesignPosterior, fisher_half_widths, ignored_outer

EPSILON = 0.05


def design_loss(half: np.ndarray, targets: Mapping[str, float]) -> np.ndarray:
    """loss of the module docstring for half-widths (..., 5) in PARAMETERS order."""
    ratios = np.stack([half[..., PARAMETERS.index(name)] / target for name, target in targets.items()], axis=-1)
    logs = np.log(ratios)
    return np.sum(np.maximum(logs, 0.0), axis=-1) + EPSILON * np.sum(logs, axis=-1)


def greedy_design(post: DesignPosterior, base_info: np.ndarray, candidate_info: np.ndarray,
                  targets: Mapping[str, float], n_tests: int,
                  base_ignored: np.ndarray | None = None) -> tuple[list[int], np.ndarray]:
    """Indices of the chosen candidates, in order, and the Fisher-predicted half-widths
    (n_tests + 1, 5) along the way.

    base_info (S, 5, 5): information of the recorded tests per draw; candidate_info (C, S, 5, 5);
    base_ignored (S, 5, 5): the recorded tests' summed ignored_outer of their information, where
    the run shares a coefficient with an ignored spread (each candidate then adds its own).
    """
    info = base_info.copy()
    candidate_ignored = None if base_ignored is None else ignored_outer(post, candidate_info.swapaxes(0, 1)).swapaxes(0, 1)
    ignored = base_ignored
    chosen: list[int] = []
    path = [fisher_half_widths(post, info, ignored)]
    for _ in range(n_tests):
        trial = fisher_half_widths(post, info[None] + candidate_info,
                                   None if ignored is None else ignored[None] + candidate_ignored)  # (C, 5)
        best = int(np.argmin(design_loss(trial, targets)))
        chosen.append(best)
        info = info + candidate_info[best]
        if ignored is not None:
            ignored = ignored + candidate_ignored[best]
        path.append(trial[best])
    return chosen, np.stack(path)


def cycled(items: Sequence, n: int) -> list:
    """items repeated in order until there are n of them."""
    return [items[i % len(items)] for i in range(n)]
