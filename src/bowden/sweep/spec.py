"""What a sweep runs: the grid of parameter points × virtual cohorts, validated, from TOML or flags.

A :class:`SweepSpec` holds the swept axes (each a tuple of values, see :mod:`bowden.sweep.axes`),
the cohorts (``participants`` drawn per seed in ``seeds``), the protocol (support conditions, speeds,
repetitions) and how the controller's lines are obtained (``identification``, ``bench``). Its points
are the Cartesian product of the axes times the seeds; a combination whose blend would have
θ̇₀₀₁ ≥ θ̇₀₉₉ is left out (and counted), and a spec with no valid point is refused.

Every point has an id: a digest of its values, its seed and everything else that changes its
results, so a re-run of the same spec finds the points it already computed.

TOML (``bowden sweep --spec FILE``)::

    name = "friction"
    participants = 17
    seeds = [0]
    repetitions = 10
    support = ["pretension", 0.25, 0.5]
    speeds = ["V1", "V2", "V3"]
    identification = "per-suit"   # or "nominal"
    bench = "paper"               # or "quick"

    [axes]
    sheath_kinetic_coefficient = [0.10, 0.14, 0.18]
    torque_constant_ratio = [0.85, 1.0, 1.15]
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.sim.parameters import SuitParameters
from bowden.sweep import axes as ax

IDENTIFICATIONS = ("per-suit", "nominal")
BENCHES = ("paper", "quick")
SUIT_CONDITIONS = tuple(name for name in c.CONDITIONS if name != c.CONDITION_NO_SUIT)
_SPEC_KEYS = (
    "name",
    "participants",
    "seeds",
    "repetitions",
    "support",
    "speeds",
    "identification",
    "bench",
    "axes",
)


@dataclass(frozen=True, kw_only=True)
class SweepPoint:
    """One point of the grid: values of the swept axes and the cohort seed.

    Attributes
    ----------
    values
        ``(axis, value)`` pairs in the spec's axis order.
    seed
        Seed of the cohort, the bench noise and every trial's noise. Points with the same seed share
        participants and noise (common random numbers), so their differences come from the
        parameters alone.
    point_id, config_id
        Digests of the point (values, seed, settings) and of its configuration (without the seed).
    """

    values: tuple[tuple[str, float], ...]
    seed: int
    point_id: str
    config_id: str

    @property
    def mapping(self) -> dict[str, float]:
        """The values as a dict."""
        return dict(self.values)

    @property
    def blend_velocities(self) -> tuple[float, float]:
        """``(θ̇₀₀₁, θ̇₀₉₉)`` of the controller at this point, rad/s."""
        return ax.blend_velocities(self.mapping)

    def suit(self, base: SuitParameters) -> SuitParameters:
        """The simulated suit of this point: ``base`` with the point's plant axes."""
        return ax.apply_plant(base, self.mapping)

    def label(self) -> str:
        """Short human-readable form, e.g. ``blend_velocity_01_rad_s=-1 seed=0``."""
        parts = [f"{name}={value:g}" for name, value in self.values]
        return " ".join([*parts, f"seed={self.seed}"])


@dataclass(frozen=True, kw_only=True)
class SweepSpec:
    """A sweep: axes × seeds, the cohort and protocol every point runs, and the identification.

    Parameters
    ----------
    name
        A label for the sweep (the preset's name, or the spec file's).
    axes
        ``(axis name, values)`` pairs; names from :data:`bowden.sweep.axes.AXES`.
    participants
        Virtual participants per cohort (paper: 17); the cohort is drawn like ``bowden study``'s.
    seeds
        One cohort (and bench) per seed.
    repetitions
        Cycles per trial (paper 10; the first is dropped by the analysis).
    conditions
        Support conditions (``contracts.CONDITIONS`` without ``no_suit``, which has no cable tension).
    speeds
        ``contracts.SPEEDS`` to run.
    identification
        ``"per-suit"``: the compensation lines are identified on the simulated bench of each point's
        suit, as a lab identifies its own suit (a torque-constant or friction change is then absorbed
        by the lines). ``"nominal"``: identified once on the default suit and used on every suit, so
        plant axes become model errors (the suit changed after identification).
    bench
        ``"paper"``: the paper's identification protocol; ``"quick"``: ``bowden study --quick-bench``'s.
    """

    name: str = "custom"
    axes: tuple[tuple[str, tuple[float, ...]], ...] = ()
    participants: int = 17
    seeds: tuple[int, ...] = (0,)
    repetitions: int = c.REPETITIONS_PER_TRIAL
    conditions: tuple[str, ...] = SUIT_CONDITIONS
    speeds: tuple[str, ...] = c.SPEEDS
    identification: str = "per-suit"
    bench: str = "paper"
    _points: tuple[SweepPoint, ...] = field(init=False, repr=False, compare=False)
    _skipped: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and self.name.strip()):
            raise ParameterError(f"name must be a non-empty string, got {self.name!r}")
        _check_int("participants", self.participants, 2, 500)
        _check_int("repetitions", self.repetitions, 2, 100)
        if not self.seeds:
            raise ParameterError("seeds must list at least one seed")
        for seed in self.seeds:
            _check_int("seeds", seed, 0, 2**32 - 1)
        if len(set(self.seeds)) != len(self.seeds):
            raise ParameterError(f"seeds lists a seed twice: {list(self.seeds)}")
        _check_choices("conditions", self.conditions, SUIT_CONDITIONS)
        _check_choices("speeds", self.speeds, c.SPEEDS)
        if self.identification not in IDENTIFICATIONS:
            raise ParameterError(
                f"identification must be one of {', '.join(IDENTIFICATIONS)}, got {self.identification!r}"
            )
        if self.bench not in BENCHES:
            raise ParameterError(f"bench must be one of {', '.join(BENCHES)}, got {self.bench!r}")
        names = tuple(name for name, _ in self.axes)
        ax.check_axis_names(names)
        for name, values in self.axes:
            _check_axis_values(name, values)
        points, skipped = self._enumerate()
        object.__setattr__(self, "_points", points)
        object.__setattr__(self, "_skipped", skipped)

    # --- the grid -----------------------------------------------------------------------------

    def points(self) -> tuple[SweepPoint, ...]:
        """Every valid point: the product of the axes (in order) for each seed."""
        return self._points

    @property
    def skipped_combinations(self) -> int:
        """Combinations of the axes left out because their blend had θ̇₀₀₁ ≥ θ̇₀₉₉."""
        return self._skipped

    @property
    def axis_names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.axes)

    def _enumerate(self) -> tuple[tuple[SweepPoint, ...], int]:
        names = self.axis_names
        combos = list(itertools.product(*(values for _, values in self.axes)))
        valid = []
        for combo in combos:
            low, high = ax.blend_velocities(dict(zip(names, combo, strict=True)))
            if low < high:
                valid.append(combo)
        if not valid:
            raise ParameterError(
                f"no point of the sweep has {ax.BLEND_01} < {ax.BLEND_99} (the raising line must take "
                "over as the elevation velocity grows); check the blend axes"
            )
        base = SuitParameters()
        context = self._context()
        points = []
        for seed in self.seeds:
            for combo in valid:
                values = tuple(zip(names, (float(v) for v in combo), strict=True))
                ax.apply_plant(base, dict(values))  # a plant value the simulator refuses fails here
                config = _digest({"values": sorted(values), "context": context})
                point = _digest({"values": sorted(values), "context": context, "seed": seed})
                points.append(SweepPoint(values=values, seed=seed, point_id=point, config_id=config))
        return tuple(points), len(combos) - len(valid)

    def _context(self) -> dict[str, Any]:
        """Everything besides values and seed that changes a point's results."""
        return {
            "participants": self.participants,
            "repetitions": self.repetitions,
            "conditions": list(self.conditions),
            "speeds": list(self.speeds),
            "identification": self.identification,
            "bench": self.bench,
        }

    # --- conversions ----------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """A JSON/TOML-able mapping that :meth:`from_mapping` reads back to an equal spec."""
        return {
            "name": self.name,
            "participants": self.participants,
            "seeds": list(self.seeds),
            "repetitions": self.repetitions,
            "support": list(self.conditions),
            "speeds": list(self.speeds),
            "identification": self.identification,
            "bench": self.bench,
            "axes": {name: list(values) for name, values in self.axes},
        }

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, source: str = "sweep spec") -> SweepSpec:
        """Build a spec from a mapping (a parsed TOML file); unknown keys are refused."""
        unknown = [key for key in data if key not in _SPEC_KEYS]
        if unknown:
            raise ParameterError(f"{source}: unknown key {unknown[0]!r}; known keys: {', '.join(_SPEC_KEYS)}")
        kwargs: dict[str, Any] = {}
        if "name" in data:
            kwargs["name"] = data["name"]
        for key in ("participants", "repetitions"):
            if key in data:
                kwargs[key] = data[key]
        if "seeds" in data:
            kwargs["seeds"] = tuple(_as_list(data["seeds"]))
        if "support" in data:
            kwargs["conditions"] = parse_support(_as_list(data["support"]))
        if "speeds" in data:
            kwargs["speeds"] = tuple(_as_list(data["speeds"]))
        for key in ("identification", "bench"):
            if key in data:
                kwargs[key] = data[key]
        if "axes" in data:
            table = data["axes"]
            if not isinstance(table, Mapping):
                raise ParameterError(f"{source}: 'axes' must be a table of axis = [values]")
            kwargs["axes"] = tuple((str(name), _as_values(str(name), v)) for name, v in table.items())
        return cls(**kwargs)

    @classmethod
    def from_toml(cls, path: str | Path) -> SweepSpec:
        """Read a spec file (format in the module docstring)."""
        file = Path(path)
        try:
            data = tomllib.loads(file.read_text(encoding="utf-8"))
        except OSError as exc:
            raise ParameterError(f"cannot read the sweep spec {file}: {exc.strerror or exc}") from None
        except UnicodeDecodeError:
            raise ParameterError(f"sweep spec {file} is not UTF-8 text (TOML files are UTF-8)") from None
        except tomllib.TOMLDecodeError as exc:
            raise ParameterError(f"sweep spec {file} is not valid TOML: {exc}") from None
        return cls.from_mapping(data, source=str(file))

    def with_axis(self, name: str, values: tuple[float, ...]) -> SweepSpec:
        """This spec with axis ``name`` set to ``values`` (replaced in place, or appended)."""
        ax.check_axis_name(name)
        axes = list(self.axes)
        for i, (existing, _) in enumerate(axes):
            if existing == name:
                axes[i] = (name, values)
                break
        else:
            axes.append((name, values))
        return replace(self, axes=tuple(axes))


def parse_support(values: list[Any]) -> tuple[str, ...]:
    """Support levels → condition names: ``"pretension"``, 0.25, 0.5 or the condition names."""
    by_fraction = {v: name for name, v in c.CONDITION_SUPPORT.items() if isinstance(v, float)}
    names = []
    for value in values:
        if isinstance(value, str) and value in SUIT_CONDITIONS:
            names.append(value)
            continue
        try:
            fraction = float(value)
        except (TypeError, ValueError):
            fraction = math.nan
        if isinstance(value, bool) or fraction not in by_fraction:
            raise ParameterError(
                f"support {value!r} is not a condition of the simulated protocol; use pretension, 0.25 "
                f"or 0.5 (or {', '.join(SUIT_CONDITIONS)})"
            )
        names.append(by_fraction[fraction])
    return tuple(names)


def parse_values(name: str, text: str) -> tuple[float, ...]:
    """Comma-separated numbers of a command-line axis (``-1,-0.5,0``)."""
    try:
        return tuple(float(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise ParameterError(
            f"sweep axis {name}: {text!r} is not a comma-separated list of numbers"
        ) from None


def _check_int(name: str, value: Any, low: int, high: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ParameterError(f"{name} must be an integer in [{low}, {high}], got {value!r}")


def _check_choices(name: str, values: tuple[str, ...], allowed: tuple[str, ...]) -> None:
    if not values:
        raise ParameterError(f"{name} must list at least one of {', '.join(allowed)}")
    for value in values:
        if value not in allowed:
            raise ParameterError(f"{name}: unknown value {value!r}; known: {', '.join(allowed)}")
    if len(set(values)) != len(values):
        raise ParameterError(f"{name} lists a value twice: {list(values)}")


def _check_axis_values(name: str, values: tuple[float, ...]) -> None:
    if not values:
        raise ParameterError(f"sweep axis {name} has no values")
    for value in values:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ParameterError(f"sweep axis {name}: {value!r} is not a finite number")
        if name in ax.BLEND_AXES:
            ax.check_blend_value(name, float(value))
    if len(set(values)) != len(values):
        raise ParameterError(f"sweep axis {name} lists a value twice: {list(values)}")


def _as_list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, list | tuple) else [value]


def _as_values(name: str, value: Any) -> tuple[float, ...]:
    items = _as_list(value)
    for item in items:
        if isinstance(item, bool) or not isinstance(item, int | float):
            raise ParameterError(f"sweep axis {name}: {item!r} is not a number")
    return tuple(float(item) for item in items)


def _digest(payload: Mapping[str, Any]) -> str:
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]
