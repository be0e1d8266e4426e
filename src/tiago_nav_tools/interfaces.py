"""What each node offers and uses on ROS, as plain data: the source of docs/ros_api.md.

Each node's entry lists its interfaces in the ROS wiki's order (see :data:`SECTIONS`). A topic,
action or service is ``(name, type, meaning)``; a transform is ``(parent, child, meaning)``.
A name written ``{scan_topic}`` is the node's parameter of that name: the page shows its
default and says which parameter sets it (and a unit test checks that every ``*_topic``,
``*_action`` and ``*_service`` parameter of the node's ``Params`` appears here). Any other name
is fixed (``~name`` is private: under the node's name). ``params`` names the module whose
``Params`` dataclass holds the node's parameters (None: the node has none).

Keep this in step with the nodes' wiring (src/tiago_nav/nodes/*.py); ``make docs`` regenerates
the page from it.
"""

# (key, heading) in the order the ROS wiki's node pages use
SECTIONS = (
    ('action_servers', 'Action servers'),
    ('action_clients', 'Action clients'),
    ('subscribed_topics', 'Subscribed topics'),
    ('published_topics', 'Published topics'),
    ('services_provided', 'Services provided'),
    ('services_called', 'Services called'),
    ('tf_provided', 'tf provided'),
    ('tf_required', 'tf required'),
)

# the lockstep topics, used by every participant when /use_lockstep is true
_TICK = ('/sim/lockstep/tick', 'tiago_nav/LockstepTick',
         'with /use_lockstep: the simulator\'s cycles, each naming the scan and odometry stamps '
         'to use')
_ACK = ('/sim/lockstep/ack', 'tiago_nav/LockstepAck',
        'with /use_lockstep: this node\'s answer for each cycle, carrying its command')
_CLOCK = ('/clock', 'rosgraph_msgs/Clock', 'simulated time (with /use_sim_time)')
# a node's reset (tiago_nav.ros.reset; docs/interfaces.md#resetting-a-running-stack)
_RESET = [('~reset/stop', 'std_srvs/Trigger',
           'a reset\'s first half: take the node\'s state down (leave the lockstep, unsubscribe, '
           'forget goals and what its latched topics last sent)'),
          ('~reset/start', 'std_srvs/Trigger',
           'a reset\'s second half: build the state anew from the parameters and the latched '
           'topics, as at start; answers once ready and its subscriptions are connected')]
# dynamic_reconfigure's standard server (tiago_nav.ros.reconfigure): rqt_reconfigure and
# `rosrun dynamic_reconfigure dynparam` use these
_RECONFIGURE_SRV = [('~set_parameters', 'dynamic_reconfigure/Reconfigure',
                     'change the run-time parameters (below); in force from the next control '
                     'cycle')]
_RECONFIGURE_TOPICS = [('~parameter_descriptions', 'dynamic_reconfigure/ConfigDescription',
                        'latched: the run-time parameters with their ranges'),
                       ('~parameter_updates', 'dynamic_reconfigure/Config',
                        'latched: their values in force')]

NODES = (
    {
        'node': 'simulator',
        'services_provided': [
            ('~reset', 'std_srvs/Trigger',
             'back to the start with the parameters as they are now (a new `~seed`): robot, '
             'noise and drift streams, contacts, faults, simulated time and the lockstep '
             'schedule as at start; the start state published again'),
        ],
        'executable': 'simulator',
        'params': 'tiago_nav.nodes.simulator',
        'launch': 'sim.launch',
        'summary': 'The pybullet mock TIAGo: a diff-drive base and a 2-D laser in the world file\'s '
                   'geometry. Publishes the laser, odometry, tf, the static map and simulated '
                   'time; obeys velocity commands.',
        'subscribed_topics': [
            ('{cmd_vel_topic}', 'geometry_msgs/Twist',
             'velocity commands in the base frame, clamped to the base\'s speed and acceleration '
             'limits; the base stops when none comes for a while'),
            ('{laser_fault_topic}', 'std_msgs/String',
             'laser fault injection for tests (tiago_nav.sim.faults)'),
            ('/sim/lockstep/ack', 'tiago_nav/LockstepAck',
             'with `~lockstep`: the participants\' answers; simulated time waits for them'),
        ],
        'published_topics': [
            ('{scan_topic}', 'sensor_msgs/LaserScan',
             'the laser in `~laser_frame`, at `~scan_rate` of simulated time (REP 117 values)'),
            ('{odom_topic}', 'nav_msgs/Odometry',
             'wheel odometry, `~odom_frame` -> `~base_frame` (drifting with odometry_model drift)'),
            ('{ground_truth_topic}', 'nav_msgs/Odometry',
             'the true pose in `~map_frame`, for tests and benchmarks only'),
            ('{map_topic}', 'nav_msgs/OccupancyGrid',
             'latched: the world\'s static geometry (movable obstacles left out)'),
            ('{map_metadata_topic}', 'nav_msgs/MapMetaData', 'latched: the map\'s metadata'),
            ('{collisions_topic}', 'std_msgs/UInt32',
             'latched: the number of contacts of the robot with anything so far'),
            ('{objects_topic}', 'tiago_nav/SimObjects',
             'latched: ground truth of the movable obstacles (any shape) and walkers (position, '
             'legs, velocity, state), in `~map_frame`; with walkers at `~scan_rate`, for tests '
             'and benchmarks only'),
            ('{markers_topic}', 'visualization_msgs/MarkerArray',
             'latched: the same drawn for RViz (with walkers only while subscribed)'),
            _CLOCK,
            ('/sim/lockstep/tick', 'tiago_nav/LockstepTick',
             'with `~lockstep`: each control cycle, naming the scan and odometry stamps to use'),
            ('/tf', 'tf2_msgs/TFMessage', 'the moving transforms below'),
            ('/tf_static', 'tf2_msgs/TFMessage', 'latched: the fixed transforms below'),
        ],
        'tf_provided': [
            ('{map_frame}', '{odom_frame}',
             'the ground truth, with `~publish_map_to_odom` (false when the localisation node '
             'publishes it)'),
            ('{odom_frame}', '{base_frame}', 'odometry'),
            ('{base_frame}', '{base_link_frame}',
             'on /tf_static, with `~publish_robot_frames` (sim.launch sets it with '
             '`robot_description:=false` and in lockstep, beside robot_state_publisher)'),
            ('{base_link_frame}', '{laser_frame}',
             'on /tf_static, with `~publish_robot_frames`'),
            ('{map_frame}', '<world_frame name>',
             'on /tf_static, when the world file declares `world_frame`: the origin of that '
             'frame (e.g. a Gazebo world\'s) in the map'),
        ],
    },
    {
        'node': 'move_base',
        'executable': 'navigation',
        'params': 'tiago_nav.nodes.navigation',
        'launch': 'navigation.launch',
        'summary': 'Navigation with ROS move_base\'s interface: plans on the static map, avoids '
                   'unmapped obstacles seen by the laser, drives to the goal pose. Serves only '
                   'once the map, a first scan and the robot\'s transform are in.',
        'action_servers': [
            ('move_base', 'move_base_msgs/MoveBaseAction',
             'goal `target_pose` in `~global_frame` (or any frame tf can transform); feedback '
             '`base_position`; SUCCEEDED within the goal tolerances, ABORTED with the reason, '
             'PREEMPTED on cancel or a new goal'),
        ],
        'subscribed_topics': [
            ('{map_topic}', 'nav_msgs/OccupancyGrid', 'latched: the static costmap\'s source'),
            ('{scan_topic}', 'sensor_msgs/LaserScan',
             'the obstacle layer, placed in the map with tf at each scan\'s stamp'),
            ('move_base_simple/goal', 'geometry_msgs/PoseStamped',
             'a goal without a client (sent on as an action goal)'),
            ('{localisation_state_topic}', 'std_msgs/String',
             'latched: the localisation\'s state; while `lost` the base stops and the goal '
             'waits, at most `~localisation_patience`'),
            _CLOCK, _TICK,
        ],
        'published_topics': [
            ('{cmd_vel_topic}', 'geometry_msgs/Twist', 'velocity commands'),
            ('~plan', 'nav_msgs/Path', 'latched: the current global plan'),
            ('~global_costmap/costmap', 'nav_msgs/OccupancyGrid',
             'latched: the costmap the planner uses (the static map, the laser\'s marks and the '
             'inflation) in costmap_2d\'s values (100 lethal, 99 inscribed, 1-98 inflation, 0 '
             'free), with a scan at most `~costmap_publish_frequency` times a second while '
             'subscribed'),
            ('move_base/goal', 'move_base_msgs/MoveBaseActionGoal',
             'the action goal made from a move_base_simple/goal'),
            _ACK,
        ] + _RECONFIGURE_TOPICS,
        'services_provided': [
            ('~make_plan', 'nav_msgs/GetPlan', 'a plan between two poses, without moving'),
            ('~clear_costmaps', 'std_srvs/Empty', 'forget the obstacle layer and the people in it'),
        ] + _RECONFIGURE_SRV + _RESET,
        'tf_required': [
            ('{global_frame}', '{odom_frame}', 'localisation (the newest)'),
            ('{odom_frame}', '{robot_base_frame}', 'odometry, at each scan\'s and cycle\'s stamp'),
            ('{robot_base_frame}', '<scan frame>', 'where the laser sits on the base'),
        ],
    },
    {
        'node': 'corridor_controller',
        'services_provided': _RECONFIGURE_SRV + _RESET,
        'executable': 'corridor_controller',
        'params': 'tiago_nav.nodes.corridor_controller',
        'launch': 'navigation.launch',
        'summary': 'The corridor control law: drives the narrow corridor ahead from the laser '
                   'alone (no map, no plan) and stops at its end.',
        'action_servers': [
            ('corridor_controller', 'tiago_nav/CorridorAction',
             'goal `max_speed`, `max_distance` (0: defaults); feedback the wall distances, '
             'lateral offset, heading error and distance; result the exit pose, the distance '
             'and the reason it stopped'),
        ],
        'subscribed_topics': [
            ('{scan_topic}', 'sensor_msgs/LaserScan', 'the laser: the only sensor of the law'),
            _CLOCK, _TICK,
        ],
        'published_topics': [
            ('{cmd_vel_topic}', 'geometry_msgs/Twist',
             'velocity commands (a stop whenever a goal ends)'),
            _ACK,
        ] + _RECONFIGURE_TOPICS,
        'tf_required': [
            ('{odom_frame}', '{base_frame}', 'the base\'s pose along the corridor'),
            ('{odom_frame}', '<scan frame>', 'the laser\'s pose at each scan\'s stamp'),
            ('{map_frame}', '{base_frame}',
             'the result\'s exit pose (in `~odom_frame` when not available)'),
        ],
    },
    {
        'node': 'obstacle_detection',
        'executable': 'obstacle_detection',
        'params': 'tiago_nav.nodes.obstacle_detection',
        'launch': 'demo.launch',
        'summary': 'Finds the obstacles that are not in the static map in the scan a call names '
                   '(combined with the scans at rest just before it): map subtraction, '
                   'clustering, one centre per cluster. Advertises its service once a usable '
                   'map has come.',
        'subscribed_topics': [
            ('{map_topic}', 'nav_msgs/OccupancyGrid', 'latched: what is not an obstacle'),
            ('{scan_topic}', 'sensor_msgs/LaserScan',
             'held (the last 4 s): a call uses the first scan stamped at or after its '
             '`scan_stamp` (0: at or after the call), with the `~rest_scans` - 1 before it '
             'taken from the same pose'),
            ('{pose_topic}', 'geometry_msgs/PoseWithCovarianceStamped',
             'held (the last 64): the covariance stamped last at or before a call\'s scan is the '
             'laser pose\'s when no pose correction was applied'),
        ],
        'published_topics': [
            ('~obstacles', 'visualization_msgs/MarkerArray',
             'latched: the last successful call\'s obstacles, in `~map_frame`'),
        ],
        'services_provided': [
            ('obstacle_detection', 'tiago_nav/DetectObstacles',
             'request thresholds, method (0 / "": the node\'s defaults) and `scan_stamp`; '
             'response `success`, the obstacles (centres in `~map_frame` and `~robot_frame`), '
             'a message (why, when `success` is false), and the pose correction applied '
             '(`pose_correction`, `pose_corrected`)'),
        ] + _RESET,
        'tf_required': [
            ('{map_frame}', '<scan frame>', 'at the scan\'s stamp'),
            ('{robot_frame}', '<scan frame>', 'at the scan\'s stamp'),
            ('{odom_frame}', '<scan frame>',
             'at the stamps of the named scan and the held ones before it: which were taken '
             'at rest'),
        ],
    },
    {
        'node': 'tiago_controller',
        'services_provided': _RESET,
        'executable': 'tiago_controller',
        'params': 'tiago_nav.nodes.tiago_controller',
        'launch': 'demo.launch',
        'summary': 'The mission proxy: serves the TiagoTask action by chaining the corridor law '
                   '(optional), move_base and the detection service, reporting each stage.',
        'action_servers': [
            ('{action_name}', 'tiago_nav/TiagoTaskAction',
             'goal pose B `x`, `y`, `yaw_deg` in `~global_frame` and `use_corridor_law`; feedback '
             'the stage (`state`), a sentence and the robot\'s pose; result the obstacles, the '
             'final pose, a message naming the stage and reason of any failure, and the last '
             'feedback `state`'),
        ],
        'action_clients': [
            ('{corridor_action}', 'tiago_nav/CorridorAction',
             'first, when asked and a corridor leads toward pose B'),
            ('{move_base_action}', 'move_base_msgs/MoveBaseAction', 'to pose B'),
        ],
        'subscribed_topics': [
            ('{scan_topic}', 'sensor_msgs/LaserScan', 'does a corridor lead toward pose B?'),
            ('{plan_topic}', 'nav_msgs/Path', 'move_base\'s plan, for the distance to go'),
            _CLOCK, _TICK,
            ('/sim/lockstep/ack', 'tiago_nav/LockstepAck',
             'with /use_lockstep: also the other participants\' answers'),
        ],
        'published_topics': [
            ('{cmd_vel_topic}', 'geometry_msgs/Twist', 'a stop whenever a goal ends'),
            ('~obstacle_markers', 'visualization_msgs/MarkerArray',
             'latched: the obstacles found, labelled'),
            ('~goal_pose', 'geometry_msgs/PoseStamped', 'latched: the current pose B'),
        ],
        'services_called': [
            ('{detection_service}', 'tiago_nav/DetectObstacles', 'once at pose B'),
        ],
        'tf_required': [
            ('{global_frame}', '{robot_frame}', 'the robot\'s pose for feedback and result'),
            ('{robot_frame}', '<scan frame>', 'where the laser sits on the base'),
        ],
    },
    {
        'node': 'localisation',
        'services_provided': [
            ('/global_localization', 'std_srvs/Empty',
             'forget the pose and search the whole map for it (as AMCL\'s)'),
        ] + _RESET,
        'executable': 'localisation',
        'params': 'tiago_nav.nodes.localisation',
        'launch': 'localisation.launch',
        'summary': 'Scan-to-map localisation: matches each scan to the static map and publishes '
                   'the map -> odom correction, as AMCL does.',
        'subscribed_topics': [
            ('{scan_topic}', 'sensor_msgs/LaserScan',
             'every scan advances the estimate; it is matched to the map after '
             '`~min_update_distance` / `~min_update_yaw_deg` of motion and for the first '
             '`~rest_updates` at rest'),
            ('{map_topic}', 'nav_msgs/OccupancyGrid', 'latched: the static map'),
            ('{initialpose_topic}', 'geometry_msgs/PoseWithCovarianceStamped',
             'resets the pose (in `~map_frame`), as AMCL takes it; a covariance reaching beyond '
             '`~search_radius` / `~search_yaw_deg` is searched as far as it reaches'),
            _CLOCK, _TICK,
        ],
        'published_topics': [
            ('{tf_topic}', 'tf2_msgs/TFMessage',
             'the map -> odom transform (another topic keeps it out of the tf tree)'),
            ('{pose_topic}', 'geometry_msgs/PoseWithCovarianceStamped',
             'the estimated pose of `~base_frame` in `~map_frame`; its covariance widened '
             'while the fit is degraded, the searched region\'s while lost'),
            ('/diagnostics', 'diagnostic_msgs/DiagnosticArray',
             'every `~diagnostic_period` and at once when the level changes: OK (tracking) / '
             'WARN (degraded) / ERROR (lost) with the reason and key values (the scans skipped '
             'so far among them)'),
            ('{state_topic}', 'std_msgs/String',
             'latched: `ok`, `degraded` or `lost`, when it changes'),
            _ACK,
        ],
        'tf_provided': [
            ('{map_frame}', '{odom_frame}',
             'at each scan (stamped its time plus `~transform_tolerance`) and re-sent at '
             '`~republish_rate`'),
        ],
        'tf_required': [
            ('{odom_frame}', '{base_frame}', 'odometry at each scan\'s stamp'),
            ('{base_frame}', '<scan frame>', 'where the laser sits on the base'),
        ],
    },
    {
        'node': 'client',
        'executable': 'client',
        'params': None,
        'launch': 'demo.launch',
        'summary': 'The command-line client: `rosrun tiago_nav client X Y YAW_DEG [--frame FRAME]` '
                   'sends pose B to tiago_controller, prints its feedback, then the obstacles '
                   'found (in FRAME, `map` by default). Exit 0 when the task succeeded, 1 when '
                   'it failed, 2 on bad input (nothing sent). Its options are its command line '
                   '(below), not parameters.',
        'action_clients': [
            ('tiago_controller', 'tiago_nav/TiagoTaskAction', 'the mission'),
        ],
        'tf_required': [
            ('map', '<--frame>', 'with `--frame` other than map: the obstacle centres are '
             'shown in that frame'),
        ],
    },
)
