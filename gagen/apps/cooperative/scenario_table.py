"""Reaching scenarios: a system's spec and one of its goals (``gagen.robots.goals``). The paper's scenarios
[COOP Section 4.2, Figs. 7-13] are the goals of the bundled specs, by goal name (``gagen reach circle``);
a user's spec is taken with its own goals, or a goal stated on the command line. Light at import (the
specs' YAML only), so the command line lists them without importing the solvers."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from gagen.registry import bundled_specs, resolve_spec
from gagen.robots.goals import Goal, load_goals


@dataclass(frozen=True)
class Scenario:
    """A system (a bundled name or a spec file) and its goal: for a ``move`` goal the similarity that moves
    its ready primitive to the target (see ``target_from``): ``translation`` (m), ``rotation`` = (world
    axis, angle in rad) about the primitive's reference point, ``dilation`` about it (rounds only)."""

    name: str
    system: str
    title: str
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[tuple[float, float, float], float] | None = None
    dilation: float = 1.0
    goal: Goal | None = None  # None: the move above

    @property
    def spec(self) -> Path:
        return resolve_spec(self.system, "cooperative", "system")


def of_goal(system: str, goal: Goal) -> Scenario:
    """The scenario of one goal of ``system`` (a bundled name or a spec path)."""
    title = goal.title or f"{Path(system).stem} reaching its goal {goal.name}"
    return Scenario(goal.name, system, title, goal.translation, goal.rotation, goal.dilation, goal)


class _Bundled(Mapping[str, Scenario]):
    """The bundled specs' goals by name, read on first use (not while the applications register)."""

    @cached_property
    def _found(self) -> dict[str, Scenario]:
        found: dict[str, Scenario] = {}
        for system, spec in bundled_specs("cooperative").items():
            for goal in load_goals(spec).values():
                found.setdefault(goal.name, of_goal(system, goal))
        return found

    def __getitem__(self, name: str) -> Scenario:
        return self._found[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._found)

    def __len__(self) -> int:
        return len(self._found)


SCENARIOS: Mapping[str, Scenario] = _Bundled()
"""The bundled specs' goals by name: the paper's scenarios."""


def scenarios_of(target: str, goal: str | None = None) -> list[Scenario]:
    """The scenarios ``gagen reach TARGET`` means: ``all`` bundled ones, one by its goal name, or the goals
    of a system (a bundled name or a spec file): the one named ``goal``, else every goal its spec states.
    A ValueError naming what there is when nothing matches."""
    if target == "all" and goal is None:
        return list(SCENARIOS.values())
    if target in SCENARIOS and goal is None:
        return [SCENARIOS[target]]
    try:
        spec = resolve_spec(target, "cooperative", "system")
    except ValueError as e:
        raise ValueError(f"{e}; nor a bundled scenario ({', '.join(SCENARIOS)}, all)") from None
    goals = load_goals(spec)
    system = target if target in bundled_specs("cooperative") else str(spec)
    if goal is not None:
        if goal not in goals:
            raise ValueError(f"--goal {goal!r}: {spec} states {', '.join(goals) or 'no goals'}")
        return [of_goal(system, goals[goal])]
    if not goals:
        raise ValueError(f"{spec} states no goals: add a goals section (gagen.robots.goals) or give one on "
                         "the command line (--translation, --rotation, --dilation)")
    return [of_goal(system, g) for g in goals.values()]
