"""The one CP-SAT set-up of the ID searches: deterministic time, a wall-clock safety net, seeded.

``time_budget`` is CP-SAT's deterministic time (about seconds on a typical machine, but
reproducible: the same model and seed give the same answer), unless the wall-clock safety
net (:data:`WALL_FACTOR` times the budget) ends the search first; :func:`solve` says when it did,
so a caller can report that the result may differ on another machine.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # OR-Tools loads when a search starts (about 0.3 s), not with every module that may search
    from ortools.sat.python import cp_model

WALL_FACTOR = 3.0
"""Wall-clock cap as a multiple of the deterministic budget."""

WORKERS = 2
"""Search workers: the machines we target have two cores."""


@dataclass(frozen=True)
class Solved:
    """A finished search: the solver (for values), whether a solution was found, proved infeasible, wall-stopped."""

    solver: cp_model.CpSolver
    found: bool
    infeasible: bool
    wall_stopped: bool


def new_model() -> cp_model.CpModel:
    """An empty CP-SAT model (OR-Tools imported here, on the first search)."""
    from ortools.sat.python import cp_model

    return cp_model.CpModel()


def solve(model: cp_model.CpModel, *, time_budget: float, seed: int, first_solution: bool = False) -> Solved:
    """Run CP-SAT on ``model``; ``first_solution`` stops at the first one (feasibility models)."""
    from ortools.sat.python import cp_model

    solver = cp_model.CpSolver()
    solver.parameters.max_deterministic_time = time_budget
    solver.parameters.max_time_in_seconds = WALL_FACTOR * time_budget
    solver.parameters.num_workers = WORKERS
    solver.parameters.interleave_search = True
    solver.parameters.random_seed = seed
    solver.parameters.stop_after_first_solution = first_solution
    status = solver.solve(model)
    return Solved(solver, status in (cp_model.OPTIMAL, cp_model.FEASIBLE), status == cp_model.INFEASIBLE,
                  solver.wall_time >= 0.99 * WALL_FACTOR * time_budget)
