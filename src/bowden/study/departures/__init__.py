"""Where a study departs from the paper: one table per family of outcomes (tracking, kinematics, iEMG,
questionnaires), the rows and tolerances they share, and which outcomes the simulator was calibrated to."""
