"""Moment arms of MoBL's deltoid in forward flexion, computed by OpenSim from the original model.

The reference values of ``tests/sim/test_myoarm.py`` (``MOBL_OPENSIM_MOMENT_ARMS_MM``) come from
this script. It needs OpenSim's Python package (``pip install opensim``; not a dependency of
bowden) and the MoBL-ARMS OpenSim model (Holzbaur, Murray & Delp 2005, Ann Biomed Eng 33:829, in
the distribution of Saul et al. 2015, Comput Methods Biomech Biomed Engin 18:1445: the OpenSim 3.3
tutorial model ``MoBL_ARMS_module6_7_CMC.osim``, SimTK project "upexdyn"). The file is not shipped
here: its licence (BSD-3 for non-commercial use) differs from bowden's.

Posture as :class:`bowden.sim.musculoskeletal.myoarm.MyoArm` poses MyoArm: plane of elevation
``elv_angle`` = 90° (forward flexion), ``shoulder_rot`` = 0, ``elbow_flexion`` = 0, the shoulder
girdle following ``shoulder_elv`` through the model's coupler constraints; OpenSim's
``Muscle.computeMomentArm`` about ``shoulder_elv`` (it accounts for the coupled coordinates).

Usage: ``python scripts/mobl_moment_arms.py MoBL_ARMS_module6_7_CMC.osim``
"""

from __future__ import annotations

import math
import sys


def main(path: str) -> int:
    import opensim  # type: ignore[import-not-found]

    model = opensim.Model(path)
    state = model.initSystem()
    coordinates = model.getCoordinateSet()
    elevation = coordinates.get("shoulder_elv")
    print(f"OpenSim {opensim.GetVersion()}, {path}")
    for degrees in (30, 60, 90):
        coordinates.get("elv_angle").setValue(state, math.radians(90), False)
        coordinates.get("shoulder_rot").setValue(state, 0.0, False)
        coordinates.get("elbow_flexion").setValue(state, 0.0, False)
        elevation.setValue(state, math.radians(degrees), True)  # assembles the coupled girdle
        model.realizePosition(state)
        arms = [1000 * model.getMuscles().get(m).computeMomentArm(state, elevation)
                for m in ("DELT1", "DELT2", "DELT3")]
        print(f"{degrees:3d}°  DELT1 {arms[0]:6.2f}  DELT2 {arms[1]:6.2f}  DELT3 {arms[2]:6.2f} mm")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: python scripts/mobl_moment_arms.py MODEL.osim", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
