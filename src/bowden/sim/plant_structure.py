"""Structural variants of the simulated suit: friction physics the compensation's own law does not have.

The nominal plant (:mod:`bowden.sim._kernels`) has the paper's single-bend friction with breakaway, a
Gaussian Stribeck curve and constant drag, a rigid stick, a sheath fixed at its ends and a constant
torque constant — the same structure the dynamic compensation models. A compensation judged only on
suits of that structure can look better than it is (issue 28). :class:`PlantStructure` switches on
what real Bowden transmissions show and the compensation does not model; every default keeps the
nominal physics bit for bit.

* **Dahl presliding** (Dahl 1968, "A solid friction model", Aerospace Corp. TOR-0158; Lampaert et al.
  2002, "Modification of the Leuven integrated friction model structure", IEEE TAC 47:683): while the
  sheath sticks the cable still moves elastically against friction that builds with displacement,
  dF/ds = σ0·(1 − F·sgn(ds)/F_c), σ0 = F_c / ``presliding_m``; the stick is hysteretic, not rigid.
* **Stribeck shape**: k(v) = k_k + (k_s − k_k)·exp(−|v/v_s|^δ), δ = ``stribeck_exponent`` (Gaussian
  δ = 2; Armstrong-Hélouvry et al. 1994, Automatica 30:1083, report δ between 0.5 and 2).
* **Capstan friction over a distributed wrap**: the friction coefficient grows with the wrap around
  the shoulder (``wrap_gain_per_rad`` per radian of elevation: Euler–Eytelwein, T_out = T_in·e^(−μφ),
  with φ growing as the arm rises) and with tension (``tension_gain_per_n``: a liner flattening under
  load, Kaneko et al. 1991, IEEE TRA 7:488, measured friction in tendon sheaths rising with tension).
* **Load-dependent viscous friction**: the sheath's drag grows with the normal force
  (``viscous_per_newton_ns_m_n`` N·s/m per N of T_in + T_out: lubricant squeezed under load).
* **Sheath play and compliance**: the sheath's ends move axially — the friction force takes up a play
  of ``play_m`` (``play_compliance_m_n`` m per N until it is taken up: backlash at the ferrules), and
  the sheath shortens under the motor-side tension by ``sheath_compliance_m_n`` m/N.
* **Torque constant drifting warm**: the winding warms by ``heating_k_nm2`` K per Nm² of delivered
  torque with time constant ``thermal_time_constant_s`` and the torque constant falls by
  ``kt_tempco_per_k`` per kelvin (NdFeB magnets lose about 0.1 %/K of flux: Hendershot & Miller 2010,
  "Design of Brushless Permanent-Magnet Machines", ch. 3). The driver's reported torque does not see it.
"""

from __future__ import annotations

from dataclasses import dataclass

from bowden.validation import check_field


@dataclass(frozen=True, kw_only=True)
class PlantStructure:
    """Structural variants of the plant's friction and motor (module docstring); defaults: none.

    Parameters
    ----------
    presliding_m
        Displacement of the cable in the stuck sheath that builds the breakaway friction (Dahl); 0: rigid
        stick. Range [0, 5e-3] m.
    stribeck_exponent
        Exponent δ of the Stribeck curve. Range [0.3, 4].
    wrap_gain_per_rad, tension_gain_per_n
        Relative growth of the friction coefficients per radian of elevation and per newton of mean
        tension. Ranges [−0.5, 2] and [0, 0.05].
    viscous_per_newton_ns_m_n
        Sheath drag per newton of T_in + T_out. Range [0, 2].
    play_m, play_compliance_m_n
        Axial play of the sheath's ends and the compliance with which friction takes it up. Ranges
        [0, 5e-3] m and [0, 1e-3] m/N.
    sheath_compliance_m_n
        Axial compression of the sheath per newton of motor-side tension. Range [0, 1e-4] m/N.
    kt_tempco_per_k, heating_k_nm2, thermal_time_constant_s
        Torque-constant loss per kelvin, steady temperature rise per Nm² and the thermal time constant
        (0: no drift). Ranges [0, 0.005] /K, [0, 50] K/Nm², [0, 3600] s.
    """

    presliding_m: float = 0.0
    stribeck_exponent: float = 2.0
    wrap_gain_per_rad: float = 0.0
    tension_gain_per_n: float = 0.0
    viscous_per_newton_ns_m_n: float = 0.0
    play_m: float = 0.0
    play_compliance_m_n: float = 0.0
    sheath_compliance_m_n: float = 0.0
    kt_tempco_per_k: float = 0.0
    heating_k_nm2: float = 0.0
    thermal_time_constant_s: float = 0.0

    def __post_init__(self) -> None:
        check_field(self, "presliding_m", 0.0, 5e-3)
        check_field(self, "stribeck_exponent", 0.3, 4.0)
        check_field(self, "wrap_gain_per_rad", -0.5, 2.0)
        check_field(self, "tension_gain_per_n", 0.0, 0.05)
        check_field(self, "viscous_per_newton_ns_m_n", 0.0, 2.0)
        check_field(self, "play_m", 0.0, 5e-3)
        check_field(self, "play_compliance_m_n", 0.0, 1e-3)
        check_field(self, "sheath_compliance_m_n", 0.0, 1e-4)
        check_field(self, "kt_tempco_per_k", 0.0, 5e-3)
        check_field(self, "heating_k_nm2", 0.0, 50.0)
        check_field(self, "thermal_time_constant_s", 0.0, 3600.0)
