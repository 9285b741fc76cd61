"""Virtual cohort: the paper's summary statistics, reproducible draws."""

from __future__ import annotations

import numpy as np
import pytest

from bowden.errors import ParameterError
from bowden.sim import VirtualParticipant, generate_cohort
from bowden.sim.participants import PAPER_HEIGHT_M, PAPER_MASS_KG


@pytest.mark.parametrize("seed", [0, 1, 7])
def test_cohort_matches_the_papers_summary(seed: int) -> None:
    cohort = generate_cohort(seed)
    assert len(cohort) == 17
    assert sum(p.subject.sex == "female" for p in cohort) == 12
    heights = np.array([p.subject.height_m for p in cohort])
    masses = np.array([p.subject.mass_kg for p in cohort])
    assert heights.mean() == pytest.approx(PAPER_HEIGHT_M[0], abs=1e-9)
    assert heights.std(ddof=1) == pytest.approx(PAPER_HEIGHT_M[1], abs=1e-9)
    assert masses.mean() == pytest.approx(PAPER_MASS_KG[0], abs=1e-9)
    assert masses.std(ddof=1) == pytest.approx(PAPER_MASS_KG[1], abs=1e-9)
    female = heights[[p.subject.sex == "female" for p in cohort]]
    male = heights[[p.subject.sex == "male" for p in cohort]]
    assert female.mean() < male.mean()
    assert len({p.participant_id for p in cohort}) == 17


def test_cohort_is_reproducible_and_seed_dependent() -> None:
    assert generate_cohort(5) == generate_cohort(5)
    assert generate_cohort(5) != generate_cohort(6)


def test_arm_dynamics_in_the_documented_range() -> None:
    for p in generate_cohort(0):
        assert 0.3 < p.inertia_kgm2 < 1.0  # de Leva 1996 segments: 0.45–0.65 kg·m² for an average adult
        assert 5.0 < p.gravity_torque_nm < 20.0


def test_invalid_participant_names_the_field() -> None:
    subject = generate_cohort(0)[0].subject
    with pytest.raises(ParameterError, match="visuomotor_lag_s"):
        VirtualParticipant(participant_id="X", subject=subject, visuomotor_lag_s=2.0)
    with pytest.raises(ParameterError, match="n_female"):
        generate_cohort(0, n_participants=5, n_female=6)


def test_wearer_friction_spread_is_log_normal_and_can_be_switched_off() -> None:
    cohort = generate_cohort(0, n_participants=400, wearer_friction_log_sd=0.3)
    scales = np.log([p.sheath_friction_scale for p in cohort])
    assert scales.std() == pytest.approx(0.3, rel=0.15)  # 400 draws: SD known to ≈ 4 %
    assert abs(scales.mean()) < 0.06
    assert all(p.sheath_friction_scale == 1.0 for p in generate_cohort(0, wearer_friction_log_sd=0.0))
    with pytest.raises(ParameterError, match="wearer_friction_log_sd"):
        generate_cohort(0, wearer_friction_log_sd=-0.1)
