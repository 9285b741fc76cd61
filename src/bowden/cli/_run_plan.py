"""What ``bowden run`` will do, worked out from its arguments before any device is opened.

The support and the study condition (each implied by the other, never contradicting it), the
reference the arm follows, the compensation model, the wearer, the controller, the participant row in
the store and the trial's metadata. Each either returns a checked value or raises a
:class:`~bowden.errors.BowdenError` naming the flag, so a bad argument never reaches the suit.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, Literal

from bowden import __version__
from bowden.contracts import BACKEND_CAN, BACKEND_SIM, CONDITION_SUPPORT_50
from bowden.control import ControllerLimits, build_controller
from bowden.errors import ParameterError
from bowden.hardware.device_record import device_record
from bowden.model import CompensationModel, Subject
from bowden.model.anthropometry import arm_model
from bowden.model.model_file import load_model
from bowden.model.model_record import model_record
from bowden.protocol.catalogue import PAPER, Catalogue
from bowden.runtime.loop import StepController
from bowden.web.reference import TrialReference
from bowden.web.trial_setup import NoAssistance, TrialSetup, condition_support, study_reference

if TYPE_CHECKING:
    from bowden.runtime.recorder import TrialInfo

MAX_LEAD_IN_S = 10.0

Support = float | Literal["pretension"] | None  # None: no suit (zero torque)


def parse_support(text: str) -> float | Literal["pretension"]:
    """``--support``: a fraction 0-1 of the gravity torque, or ``pretension``."""
    if text == "pretension":
        return "pretension"
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(f"--support must be a fraction 0-1 or 'pretension', got {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise ParameterError(f"--support must be within 0-1, got {value}")
    return value


def support_of(condition: str, catalogue: Catalogue = PAPER) -> Support:
    """The support a study condition stands for: the rule ``bowden serve`` applies too."""
    return condition_support(condition, catalogue)


def support_and_condition(
    support_text: str | None, given: str | None, catalogue: Catalogue = PAPER
) -> tuple[Support, str | None]:
    """The run's support and condition, each from the other when absent (the ``catalogue``'s).

    Neither given: 50 % support. A condition that contradicts the support is refused, so that no
    trial is ever stored under a condition it did not run in. A support no condition has (0.3) gives
    no condition: fine for a free run, refused by :func:`bowden.cli.run.run` when the trial is recorded.
    A condition the catalogue does not know (the paper's, ``--define-condition``, the store's) is refused.
    """
    if given is not None and given not in catalogue.condition_names:
        raise ParameterError(
            f"--condition {given} is unknown (known: {', '.join(catalogue.condition_names)}); define "
            "your own with --define-condition NAME=SUPPORT"
        )
    if support_text is None:
        return (support_of(given, catalogue) if given is not None else 0.5), given or CONDITION_SUPPORT_50
    support = parse_support(support_text)
    named = catalogue.conditions_with_support(support)
    if given is None:
        return support, named[0] if named else None
    if given not in named:
        expected = support_of(given, catalogue)
        wanted = (
            "no --support (no suit: the motor stays at zero torque)"
            if expected is None
            else f"--support {expected}"
        )
        raise ParameterError(
            f"--condition {given} contradicts --support {support_text}: {given} means {wanted}"
        )
    return support, given


def speed_peak(args: argparse.Namespace, catalogue: Catalogue = PAPER) -> float:
    """``--speed``'s peak elevation speed, °/s (the paper's, ``--define-speed``'s or the store's)."""
    if args.speed not in catalogue.speed_names:
        raise ParameterError(
            f"--speed {args.speed} is unknown (known: {', '.join(catalogue.speed_names)}); define "
            "your own with --define-speed NAME=DEG_S"
        )
    return catalogue.peak_deg_s(args.speed)


def run_reference(args: argparse.Namespace, catalogue: Catalogue = PAPER) -> TrialReference:
    """The run's reference: ``--lead-in`` of rest, then the whole cycles at ``--speed`` that fit."""
    if not (math.isfinite(args.lead_in) and 0.0 <= args.lead_in <= MAX_LEAD_IN_S):
        raise ParameterError(f"--lead-in must be within 0-{MAX_LEAD_IN_S:g} s, got {args.lead_in}")
    peak = speed_peak(args, catalogue)
    period = study_reference(args.speed, lead_in_s=0.0, repetitions=1, peak_deg_s=peak).cycle.period_s
    repetitions = max(1, min(100, math.floor((args.duration - args.lead_in) / period + 1e-9)))
    return study_reference(args.speed, lead_in_s=args.lead_in, repetitions=repetitions, peak_deg_s=peak)


def run_model(args: argparse.Namespace) -> CompensationModel:
    if args.model is not None:
        return load_model(args.model)
    from bowden.sim.parameters import SuitParameters

    return CompensationModel.from_friction(k=SuitParameters().sheath.kinetic_coefficient)


_WEARER_FLAGS: Final = {
    "height_m": "--height",
    "mass_kg": "--mass",
    "sex": "--sex",
    "hand_load_kg": "--hand-load",
}


def wearer(args: argparse.Namespace) -> Subject:
    """The wearer's anthropometrics, checked with the hand load (errors name the flag)."""
    try:
        subject = Subject(height_m=args.height, mass_kg=args.mass, sex=args.sex)
        arm_model(subject, args.hand_load)
    except ParameterError as error:
        text = str(error)
        field = next((name for name in _WEARER_FLAGS if text.startswith(name)), None)
        if field is None:
            raise ParameterError(f"wearer: {text}") from None
        # "height_m must be ..." → "--height must be ...": the flag the user typed, not the field.
        raise ParameterError(_WEARER_FLAGS[field] + text[len(field):]) from None
    return subject


def controller_for(
    model: CompensationModel,
    support: Support,
    subject: Subject,
    hand_load_kg: float,
    *,
    compensation: Literal["paper", "dynamic"] | None = None,
    rate_hz: float = 500.0,
    speed: str | None = None,
) -> StepController:
    """The condition's controller: none (zero torque) without the suit, else the sensorless one.

    Its nominal period is the loop's, which the dynamic compensation's estimator is tuned for;
    ``speed`` (``--speed``) picks the model's recommended compensation for that cell.
    """
    if support is None:
        return NoAssistance()
    limits = ControllerLimits(nominal_period_s=1.0 / rate_hz)
    return build_controller(
        model=model, support=support, subject=subject, hand_load_kg=hand_load_kg, limits=limits,
        compensation=compensation, speed=speed,
    )


# The wearer's flags, the registry's value each stands for, and the value without a registration.
_REGISTERED: Final = (
    ("height", "--height", "height_m", 1.70),
    ("mass", "--mass", "mass_kg", 63.0),
    ("sex", "--sex", "sex", "female"),
    ("hand_load", "--hand-load", "hand_load_kg", 0.5),
)


def fill_wearer(args: argparse.Namespace, participant: str) -> bool:
    """Take the wearer's flags left out from the registry of ``--record`` (True if registered there).

    A registered participant's anthropometrics are never typed again; a flag that contradicts the
    registry is refused (naming both values). Without a registration the defaults stand in.
    """
    known = None
    if args.record is not None and Path(args.record).is_file():
        from bowden.web.registry import Registry

        known = Registry(args.record).find(participant)
    registered = known.to_json() if known is not None else {}
    for attribute, flag, field, default in _REGISTERED:
        given, stored = getattr(args, attribute), registered.get(field)
        if stored is None:
            setattr(args, attribute, default if given is None else given)
        elif given is None:
            setattr(args, attribute, stored)
        elif given != stored:
            raise ParameterError(
                f"{flag} {given} contradicts the registry: {participant} is registered in {args.record} "
                f"with {field} {stored}; leave {flag} out to use it, or register another participant"
            )
    return known is not None


def record_participant(path: Path, participant: str, subject: Subject, hand_load_kg: float) -> None:
    """Register the wearer in the store's registry, or check that it holds the same values.

    Opening the store here also proves the ``--record`` path usable before any device is opened.
    A participant stored with other anthropometrics is refused rather than overwritten: the
    defaults of --height/--mass/--sex must never replace what a study recorded.
    """
    from bowden.store.study_store import StudyStore  # cli wires study and runtime together
    from bowden.web.registry import Participant, Registry

    with StudyStore(path, synchronous="FULL") as store:
        stored = store.participants()
        row = stored[stored["id"] == participant]
        if row.empty:
            Registry(path).register(Participant(
                participant=participant, subject=subject, arm_side=None, hand_load_kg=hand_load_kg
            ))
            return
        known = Subject(
            height_m=float(row["height_m"].iloc[0]),
            mass_kg=float(row["mass_kg"].iloc[0]),
            sex=row["sex"].iloc[0],
        )
        if not (
            known.sex == subject.sex
            and math.isclose(known.height_m, subject.height_m, rel_tol=1e-9)
            and math.isclose(known.mass_kg, subject.mass_kg, rel_tol=1e-9)
        ):
            raise ParameterError(
                f"participant {participant} is in {path} as {known.sex}, {known.height_m:g} m, "
                f"{known.mass_kg:g} kg, but this run says {subject.sex}, {subject.height_m:g} m, "
                f"{subject.mass_kg:g} kg: pass --sex/--height/--mass as stored, or another --participant"
            )


def trial_setup_of(
    args: argparse.Namespace,
    participant: str,
    condition: str,
    support: Support,
    reference: TrialReference,
    subject: Subject,
    catalogue: Catalogue = PAPER,
) -> TrialSetup:
    """The run as the browsers see it (the console's trial fields, also the trial's metadata)."""
    return TrialSetup(
        participant=participant,
        condition=condition,
        speed=args.speed,
        speed_peak_deg_s=catalogue.peak_deg_s(args.speed),
        support=support,
        repetitions=reference.repetitions,
        lead_in_s=reference.start_s,
        subject=subject,
        hand_load_kg=args.hand_load,
    )


def trial_info(
    args: argparse.Namespace,
    setup: TrialSetup,
    reference: TrialReference,
    compensation: str | None = None,
    model: CompensationModel | None = None,
) -> TrialInfo:
    """The trial's row in the store; its metadata follows the keys ``bowden serve`` writes.

    ``compensation`` is the one the controller uses (None: no controller, the no-suit condition);
    ``model`` the compensation model (loaded from ``--model``): its SHA-256 and coefficients are
    recorded (:mod:`bowden.model.model_record`), not only the file's name.
    """
    # The simulated arm follows the reference and --serve shows it; otherwise (the real suit, no
    # display) nobody follows it and the trial holds whatever number of cycles the wearer made.
    followed = args.backend == BACKEND_SIM or args.serve
    metadata: dict[str, Any] = {
        "source": "bowden run --serve" if args.serve else "bowden run",
        "backend": BACKEND_SIM if args.backend == BACKEND_SIM else BACKEND_CAN,
        "rate_hz": args.rate,
        "compensation": compensation,
        "bowden_version": __version__,
        "model": str(args.model) if args.model else "ideal (simulation)",
        **(model_record(model, args.model) if model is not None else {}),
        **device_record(args.motor, args.firmware, args.imu),  # which actuator and IMU it ran on
        **{k: v for k, v in setup.to_json().items() if k not in ("participant", "condition")},
    }
    if followed:
        metadata["reference"] = reference.to_json()
    else:
        metadata["repetitions"] = None  # any number: the analysis takes the cycles it finds
    # Imported here: the recorder's module brings pandas, which building the parser does not need.
    from bowden.runtime.recorder import TrialInfo

    return TrialInfo(
        participant=setup.participant,
        condition=setup.condition,
        speed=args.speed,
        support=setup.recorded_support,
        metadata=metadata,
    )
