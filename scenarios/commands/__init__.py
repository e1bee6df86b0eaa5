"""The commands of ``offtrack``, one module a room; :mod:`scenarios.cli` registers them on its app, in one table.

* :mod:`~scenarios.commands.options` — the options several commands take, each declared once;
* :mod:`~scenarios.commands.terminal` — the consoles, the exit codes and the error handling of a command body;
* :mod:`~scenarios.commands.scenario_input` — a scenario's options and ``--set`` as dotted overrides;
* :mod:`~scenarios.commands.run_commands` — ``list``, ``run``, ``config``, ``report``, ``export``;
* :mod:`~scenarios.commands.study_commands` — ``compare``, ``study``, ``assess``, ``tune``;
* :mod:`~scenarios.commands.camera_commands` — ``render``, ``estimate``, ``vo-eval``, ``calibrate``, ``animate``.
"""
