"""Musculoskeletal virtual participants: MyoArm (MuJoCo) and static optimisation (issue 30).

:mod:`~bowden.sim.musculoskeletal.myoarm` poses MyoArm and gives moment arms, muscle forces and
inverse dynamics with the hand load and the suit's cable; :mod:`.static_optimisation` shares the
required torques among the muscles (least Σ a²); :mod:`.activations` maps the result to the paper's
electrodes (the one mapping); :mod:`.table` and :mod:`.trial` are the study's path
(``--muscles musculoskeletal``, imported by :meth:`bowden.sim.results.TrialSimulation.activations`
only then). Needs the ``msk`` extra.
"""
