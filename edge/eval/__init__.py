"""Evaluations: the experiment grids, runners, claims and plots behind docs/results/.

One module per evaluation, each a thin layer over pure functions of the packages below it
(scene generation and image formation in `edge.sim`, decoding in `edge.decode`, the adaptive loop
in `edge.edc`, light-source models in `edge.source`), decoding with the same
`edge.decode.DecodeSettings` a profile's ``[decoder]`` / ``[camera]`` sections give:

    edge.eval.sweep     the paper's simulation curves (``edge eval sweep``, tools/eval_sweep.py)
    edge.eval.edc       EDC error maps and the adaptive loop vs baselines (``edge edc run|eval``, tools/eval_edc.py)
    edge.eval.event_sl  event-camera SL with a source-coded dot projector (``edge source event-demo``)
    edge.eval.curtain   two light curtains with and without source codes (``edge source curtain-demo``)
    edge.eval.report    shared helpers: matplotlib (Agg), markdown tables, settings as profile sections

Imports point down: eval -> sim / decode / edc / source; only `edge.commands` and tools/ import eval.
"""
