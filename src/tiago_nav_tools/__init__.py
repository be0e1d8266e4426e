"""The evaluation and tooling of tiago_nav, apart from the runtime package (:mod:`tiago_nav`),
which never imports it:

- :mod:`.evaluate`: the batch evaluator (``rosrun tiago_nav evaluate SUITE.yaml --out DIR``,
  docs/evaluation.md) with its run supervisors and its judging rules (:mod:`.evaluate.inview`:
  what "in view" means; :mod:`.evaluate.matching`: found centres matched to true ones);
- :mod:`.benchmarks`: the benchmark registry (``make bench``);
- :mod:`.docs` and :mod:`.interfaces`: the generated docs pages (``make docs``);
- :mod:`.testing`: test doubles, the mission harness and the real-data replay used by the tests
  and the benchmarks.
"""
