"""The nodes' code: each ``nodes/<name>`` executable is a door into ``tiago_nav.nodes.<name>.main()``
(splitting the executable from the code makes it importable and testable, as in
nmea_navsat_driver). Each module wires ROS (subscribers, publishers, tf, action servers) around
decisions that take plain values, so unit tests can drive them with :mod:`tiago_nav_tools.testing`
fakes. ``python3 -m tiago_nav.nodes`` rewrites ``config/*.yaml`` from the parameter dataclasses.
"""
import os

# One BLAS thread per node. The nodes' linear algebra is on tiny matrices (3x3 inverses, wall
# fits), and OpenBLAS's worker threads, one per core, spin (sched_yield) after each call: measured
# on the course mission at full speed, localisation alone spent 7 s of system time in 13 s of
# wall time, slowing every other node on a 2-core machine. Set before numpy is first imported
# (every node's module is imported through this package); a value the user set is kept.
for _name in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_name, '1')

# node module -> its file under config/; each module's ``Params`` is its parameter dataclass,
# whose docstring's first line titles the file
CONFIG_FILES = {
    'simulator': 'simulator.yaml',
    'navigation': 'navigation.yaml',
    'corridor_controller': 'corridor.yaml',
    'obstacle_detection': 'detection.yaml',
    'tiago_controller': 'tiago_controller.yaml',
    'localisation': 'localisation.yaml',
}


def config_text(module_name):
    """The text ``config/<file>.yaml`` of a node module must hold."""
    import importlib
    from tiago_nav.params import config_yaml
    cls = importlib.import_module('tiago_nav.nodes.' + module_name).Params
    title = (cls.__doc__ or module_name).strip().split('\n\n')[0]
    return config_yaml(cls, ' '.join(title.split()))
