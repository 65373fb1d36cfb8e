"""What a run did (pure numpy + the MCAP reader): sinusoid fits and vibration figures (``fits``), the
run's signals and its summary judged against the scenario's bounds (``run_summary``), and the report of
any MCAP with its plots (``run_report``, ``run_plots``) -- one computation, two presentations."""
