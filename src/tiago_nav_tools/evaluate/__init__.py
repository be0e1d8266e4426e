"""The batch evaluator (``rosrun tiago_nav evaluate SUITE.yaml --out DIR``, docs/evaluation.md).

- :mod:`.suite`: the suite file, its expansion into frozen runs and their ids (no ROS);
- :mod:`.metrics`: each metric defined once, as pure functions (no ROS);
- :mod:`.report`: results.csv, summary.md/json, junit.xml, plots, manifest (no ROS);
- :mod:`.run`: one run's process tree: its supervisor (:mod:`tiago_nav_tools.evaluate.supervisor`)
  in a session of its own, the watchdog, teardown, judging;
- :mod:`.engine`: Dask distributed (the only module that imports dask);
- :mod:`.cli`: the command line.
"""
