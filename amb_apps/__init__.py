"""
amb_apps: the applications, on top of every part (the top layer; no project package imports it).

Command lines and what they run: ``run_cli`` (``amb-run``: the nodes over DDS; ``run_processes``:
its node processes; ``system``: the node set and parameters of a run, shared with the launch
file), ``sim_cli`` (``amb-sim``) with
the in-process loop ``closed_loop`` and ``plant_models`` (models from the simulated rig),
``report_cli`` (``amb-report``: ``report_metrics``, ``report_figures``), ``compare_cli``
(``amb-compare``: ``compare_cases``, ``compare_runs``, ``compare_report``), ``prediction_cli``
(``amb-prediction``), ``acceptability`` (``amb-acceptability``) and ``acceptance``,
``eval_cli`` (``amb-fault-eval``: ``evaluation``, ``eval_figures``) and ``reproduce``
(``make reproduce``).
"""
