"""eval: rules, scorer, trials, sweeps and plots.

The scorer side: :mod:`eval.rules` (scoring presets as YAML data),
:mod:`eval.poi_file` (the competition POI CSV reader and writer),
:mod:`eval.scorer` (RULES.md "Scoring presets"), :mod:`eval.score_report`
(tables and JSON), :mod:`eval.score_cli` (``poibench score``) and
:mod:`eval.map_plot` (the competition's 2D map conventions).
"""
