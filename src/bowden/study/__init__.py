"""The study: the pipelines that run and analyse one (pipeline, analyze, trial_runner, statistics...),
and its rooms: report/ (the HTML report, figures, tables), departures/ (where a study departs from the
paper), compensation/ (the paper's lines against the dynamic model), emg/ (sEMG import) and
paper_values/ (the paper's numbers). The store it writes is :mod:`bowden.store`."""
