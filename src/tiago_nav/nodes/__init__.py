"""The nodes' code: each ``nodes/<name>`` executable is a door into ``tiago_nav.nodes.<name>.main()``
(splitting the executable from the code makes it importable and testable, as in
nmea_navsat_driver). Each module wires ROS (subscribers, publishers, tf, action servers) around
decisions that take plain values, so unit tests can drive them with :mod:`tiago_nav.testing`
fakes. ``python3 -m tiago_nav.nodes`` rewrites ``config/*.yaml`` from the parameter dataclasses.
"""

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
