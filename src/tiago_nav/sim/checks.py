"""The simulator node's checks of its parameters against the time source and the world file
(no ROS here): each raises with a sentence naming the parameter or the file."""
from tiago_nav.params import ParamError
from tiago_nav.sim.world import WorldError


def check_time_source(params, use_sim_time):
    """Raise :class:`ParamError` unless ``real_time_factor`` can be kept: without simulated
    time the simulator runs at wall-clock pace."""
    if not use_sim_time and params.real_time_factor != 1.0:
        raise ParamError('needs /use_sim_time true', 'real_time_factor',
                         'parameter ~real_time_factor: %g needs /use_sim_time true (without '
                         'simulated time the simulator runs at wall-clock pace)' % params.real_time_factor)
    if not use_sim_time and params.lockstep:
        raise ParamError('needs /use_sim_time true', 'lockstep',
                         'parameter ~lockstep: needs /use_sim_time true')


def check_world_frame(world, params):
    """Raise :class:`WorldError` when the world file's ``world_frame`` takes the name of one
    of the frames the simulator publishes (tf would get two parents for it)."""
    wf = world.world_frame
    own = (params.map_frame, params.odom_frame, params.base_frame, params.base_link_frame,
           params.laser_frame)
    if wf is not None and wf.name in own:
        raise WorldError('%s: world_frame.name %r is one of the simulator\'s own frames (%s)'
                         % (world.source, wf.name, ', '.join(own)))
