"""What a run did (pure numpy + the MCAP reader): sinusoid fits and vibration figures (``fits``), the
run's signals (``run_signals``) and its summary: what the recording covers (``run_coverage``), the vibration
and tissue figures (``vibration_figures``, ``tissue_figures``) judged against the scenario's bounds
(``run_verdict``); and the report of any MCAP with its plots (``run_report``, ``run_plots``) -- one
computation, two presentations."""
