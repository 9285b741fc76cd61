"""Musculoskeletal virtual participants: MyoArm (MuJoCo) and static optimisation (issue 30).

:mod:`~bowden.sim.musculoskeletal.myoarm` poses MyoArm and gives moment arms, muscle forces and
inverse dynamics with the hand load and the suit's cable; :mod:`.static_optimisation` shares the
required torques among the muscles (least Σ a²); :mod:`.activations` maps the result to the paper's
electrodes. Needs the ``msk`` extra; nothing else in ``bowden.sim`` imports it yet.
"""
