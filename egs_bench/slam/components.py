"""The seams of the SLAM system: the parts a researcher can replace.

:class:`~egs_bench.slam.system.SlamSystem` runs the frame loop and asks three components for
the decisions inside it:

* a :class:`Tracker` estimates each frame's exposure trajectory against the fixed map;
* a :class:`MapOptimiser` builds the map on frame 0 and refines it on each keyframe window;
* a :class:`KeyframePolicy` decides which frames become keyframes and which leave the window;
* the loss terms (:mod:`egs_bench.slam.loss_terms`) that tracking and mapping minimise.

:class:`SlamComponents` holds a factory for each, called once per run with the run's
:class:`~egs_bench.slam.context.SlamContext`; its defaults are the built-in EGS-SLAM / MonoGS
parts, configured by the method's :class:`~egs_bench.slam.config.SlamConfig`. A factory may
wrap the default (the ground-truth oracles of ``benchmarks/oracle_tracking.py`` do) or replace
it. ``docs/guide/extending.md`` shows how, with an example that the test suite runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from egs_bench.errors import ConfigError
from egs_bench.render import GaussianMap
from egs_bench.slam.config import GROUPS, KeyframeConfig, LossConfig
from egs_bench.slam.context import SlamContext
from egs_bench.slam.convergence import ConvergenceTest
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.frames import FrameObs, FrameState
from egs_bench.slam.keyframes import KeyframeCandidate, MonoGSKeyframes
from egs_bench.slam.loss_terms import LOSS_TERMS, LossTerm
from egs_bench.slam.mapper import Mapper
from egs_bench.slam.scheduling import ConcurrentMapping, MapRound
from egs_bench.slam.tracker import GradientTracker, TrackRequest, TrackResult


@runtime_checkable
class Tracker(Protocol):
    """Estimates one frame's exposure trajectory; the map is not changed."""

    def track(self, gmap: GaussianMap, crf: CameraResponse, request: TrackRequest
              ) -> TrackResult:
        """The frame's estimated :class:`~egs_bench.slam.frames.FrameState` (poses
        world-to-camera [4, 4] float64), its final loss and the iterations it took."""
        ...


@runtime_checkable
class MapOptimiser(Protocol):
    """Optimises the map (and keyframe poses and exposures, if it chooses) in place."""

    def optimise(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
                 window: list[int], all_keyframes: list[int], iterations: int,
                 *, initial: bool = False, fixed_end_pose: int | None = 0,
                 report: Callable[[int, int], None] | None = None) -> float:
        """One mapping round over ``window`` (newest first); ``initial`` on frame 0.
        Returns the last loss."""
        ...

    def begin_round(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
                    window: list[int], all_keyframes: list[int], iterations: int,
                    *, initial: bool = False, fixed_end_pose: int | None = 0,
                    report: Callable[[int, int], None] | None = None) -> MapRound:
        """The round of :meth:`optimise` (same arguments) to be run in slices beside tracking
        (``mapping.mapping_mode = "concurrent"``, :mod:`egs_bench.slam.scheduling`)."""
        ...

    def refine(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
               keyframes: list[int], iterations: int) -> float:
        """The final refinement after the last frame (``mapping.refine_iters`` > 0)."""
        ...


@runtime_checkable
class KeyframePolicy(Protocol):
    """Keyframe selection and window maintenance."""

    def is_keyframe(self, candidate: KeyframeCandidate) -> bool:
        ...

    def update_window(self, window: list[int], new_kf: int, visibility: dict[int, np.ndarray],
                      poses_cw: dict[int, np.ndarray]) -> tuple[list[int], list[int]]:
        """``(window with new_kf in front, removed keyframes)``; visibility bool [N] and
        world-to-camera poses [4, 4] by keyframe."""
        ...


def check_part(part: object, protocol: type, role: str) -> None:
    """Refuse a component that lacks a method of its protocol, before the run starts.

    Raises:
        ConfigError: naming the component, its role and the missing methods.
    """
    if isinstance(part, protocol):
        return
    needed = [name for name, value in vars(protocol).items()
              if callable(value) and not name.startswith("_")]
    missing = [name for name in needed if not callable(getattr(part, name, None))]
    raise ConfigError(f"the {role} {type(part).__name__} is not a {protocol.__name__}: it has "
                      f"no {', '.join(missing)}()")


TrackerFactory = Callable[[SlamContext], Tracker]
MapperFactory = Callable[[SlamContext, GaussianMap, CameraResponse, np.random.Generator],
                         MapOptimiser]
KeyframePolicyFactory = Callable[[SlamContext], KeyframePolicy]


class MonoGSKeyframePolicy(MonoGSKeyframes):
    """The default keyframe policy: MonoGS's rules (``keyframes``) with the configured window
    size (``budget.window_size``)."""

    Config: ClassVar[type] = KeyframeConfig

    def __init__(self, ctx: SlamContext) -> None:
        super().__init__(ctx.cfg.keyframes, ctx.cfg.budget.window_size)


#: which configuration group each replaceable part reads (its ``Config`` extends the group's
#: built-in class)
ROLE_GROUPS = {"tracker": "tracking", "mapper": "mapping", "keyframes": "keyframes"}

#: the built-in parts that every method uses (not factories of :class:`SlamComponents`): by
#: role, the class and the group whose fields its ``Config`` (a base class of the group's
#: built-in class) declares; recorded in ``config.yaml`` with the replaceable parts
FIXED_PARTS: dict[str, tuple[type[ConvergenceTest] | type[ConcurrentMapping], str]] = {
    "convergence": (ConvergenceTest, "tracking"), "schedule": (ConcurrentMapping, "mapping")}


def import_path(obj: object) -> str:
    """``module:qualified.name`` of a class or function (as :func:`~egs_bench.runs.registry`
    resolves ``--method module:attribute``); a part defined inside a function has
    ``<locals>`` in its name and cannot be imported back."""
    module = getattr(obj, "__module__", None) or type(obj).__module__
    name = getattr(obj, "__qualname__", None) or type(obj).__qualname__
    return f"{module}:{name}"


@dataclass(frozen=True)
class SlamComponents:
    """Factories of the replaceable parts; the defaults are the built-in ones.

    Attributes:
        tracker: ``tracker(ctx) -> Tracker``.
        mapper: ``mapper(ctx, gmap, crf, rng) -> MapOptimiser``; ``rng`` is the run's seeded
            generator for random view choices.
        keyframes: ``keyframes(ctx) -> KeyframePolicy``.
        loss_terms: the terms of the tracking and mapping loss, in the context
            (:mod:`egs_bench.slam.loss_terms`).
    """

    tracker: TrackerFactory = GradientTracker
    mapper: MapperFactory = Mapper
    keyframes: KeyframePolicyFactory = MonoGSKeyframePolicy
    loss_terms: tuple[LossTerm, ...] = LOSS_TERMS

    def config_classes(self) -> dict[str, type]:
        """By configuration group, the config class the part in it reads: a factory's
        ``Config`` class attribute (a frozen dataclass extending the group's built-in class,
        whose own fields ``--set GROUP.FIELD`` reaches), else the built-in class; the groups
        no part reads (``method``, ``budget``, ...) are the built-in ones."""
        out: dict[str, type] = dict(GROUPS)
        for role, group in ROLE_GROUPS.items():
            declared = getattr(getattr(self, role), "Config", None)
            out[group] = declared if declared is not None else GROUPS[group]
        out["loss"] = loss_config_class(self.loss_terms)
        return out

    def record(self) -> dict[str, Any]:
        """What the run folder's ``config.yaml`` records of the parts: each factory's import
        path and the group (and config class) it reads, the same for the convergence rule and
        the mapping schedule (:data:`FIXED_PARTS`), and each loss term's name and the import
        path of its value function."""
        classes = self.config_classes()
        out: dict[str, Any] = {
            role: {"target": import_path(getattr(self, role)), "config": group,
                   "config_class": import_path(classes[group])}
            for role, group in ROLE_GROUPS.items()}
        out.update(fixed_parts_record())
        out["loss_terms"] = [{"name": term.name, "value": import_path(term.value)}
                             for term in self.loss_terms]
        out["loss_config_class"] = import_path(classes["loss"])
        return out


def fixed_parts_record() -> dict[str, dict[str, str]]:
    """The record of :data:`FIXED_PARTS`, as in :meth:`SlamComponents.record` (a
    ``config.yaml`` written before they were recorded implies these)."""
    return {role: {"target": import_path(part), "config": group,
                   "config_class": import_path(part.Config)}
            for role, (part, group) in FIXED_PARTS.items()}


def loss_config_class(terms: tuple[LossTerm, ...]) -> type:
    """The ``loss`` group's class for ``terms``: the most derived of the terms' ``config``
    classes (each term's fields are then in it), or :class:`LossConfig`.

    Raises:
        TypeError: two terms declare configs neither of which extends the other (make one
            term's config extend the other's, so one class holds both terms' fields).
    """
    chosen: type = LossConfig
    for term in terms:
        if term.config is None or issubclass(chosen, term.config):
            continue
        if not issubclass(term.config, chosen):
            raise TypeError(f"loss term {term.name!r} declares {term.config.__name__}, "
                            f"unrelated to {chosen.__name__} of another term: one must extend "
                            "the other")
        chosen = term.config
    return chosen
