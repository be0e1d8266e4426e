#!/usr/bin/env python3
"""Draw docs/graph.png: which node talks to which in demo.launch (matplotlib, no Graphviz).

    /usr/bin/python3 docs/make_graph.py [--out docs/graph.png]

Boxes are nodes (name, and the executable when it differs); arrows are actions, services and
topics, coloured by kind. Edit NODES and EDGES when an interface changes.
"""
import argparse
import os

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt                       # noqa: E402
from matplotlib.patches import FancyBboxPatch         # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))

# name: (x, y, second line)
NODES = {
    'client': (0.50, 0.93, 'rosrun tiago_nav client / your code'),
    'tiago_controller': (0.50, 0.73, 'the mission proxy'),
    'corridor_controller': (0.14, 0.50, 'corridor law'),
    'move_base': (0.50, 0.50, 'executable: navigation'),
    'obstacle_detection': (0.86, 0.50, 'scan minus map'),
    'localisation': (0.14, 0.21, 'map -> odom, /amcl_pose'),
    'robot_state_publisher': (0.86, 0.21, 'URDF fixed frames'),
    'simulator': (0.50, 0.07, 'pybullet mock TIAGo'),
}

KINDS = {
    'action': ('#1f4e9c', '-', 'action'),
    'service': ('#6a3d9a', '-', 'service'),
    'cmd': ('#c0392b', '-', 'velocity command'),
    'sensor': ('#2e8b57', '-', 'sensor data, map, tf'),
    'lockstep': ('#888888', '--', 'lockstep tick / ack'),
}

# (from, to, label, kind, curvature, label position along the arrow)
EDGES = [
    ('client', 'tiago_controller', 'tiago_controller (TiagoTask)', 'action', 0.0, 0.5),
    ('tiago_controller', 'corridor_controller', 'corridor_controller (Corridor)', 'action', 0.0, 0.6),
    ('tiago_controller', 'move_base', 'move_base (MoveBase)', 'action', 0.0, 0.35),
    ('tiago_controller', 'obstacle_detection', 'obstacle_detection (DetectObstacles)', 'service', 0.0, 0.6),
    ('corridor_controller', 'simulator', '/mobile_base_controller/cmd_vel', 'cmd', 0.0, 0.45),
    ('move_base', 'simulator', 'cmd_vel', 'cmd', 0.0, 0.8),
    ('simulator', 'localisation', '/scan, /map, odom tf', 'sensor', 0.0, 0.5),
    ('localisation', 'move_base', 'tf map -> odom', 'sensor', 0.0, 0.7),
    ('simulator', 'obstacle_detection', '/scan, /map, tf', 'sensor', 0.0, 0.45),
    ('robot_state_publisher', 'obstacle_detection', '/tf_static', 'sensor', 0.0, 0.5),
    ('simulator', 'robot_state_publisher', '/clock', 'sensor', 0.0, 0.5),
]

BOX_W, BOX_H = 0.23, 0.085


def edge_point(src, dst):
    """Where the line from the centre of ``src`` toward ``dst`` leaves the box of ``src``."""
    (x0, y0), (x1, y1) = src, dst
    dx, dy = x1 - x0, y1 - y0
    scale = min((BOX_W / 2) / abs(dx) if dx else float('inf'),
                (BOX_H / 2) / abs(dy) if dy else float('inf'))
    return x0 + dx * scale, y0 + dy * scale


def draw(out):
    fig, ax = plt.subplots(figsize=(12, 8.2), dpi=100)
    ax.set_xlim(-0.03, 1.03)
    ax.set_ylim(-0.08, 1.0)
    ax.axis('off')
    for name, (x, y, sub) in NODES.items():
        ax.add_patch(FancyBboxPatch((x - BOX_W / 2, y - BOX_H / 2), BOX_W, BOX_H,
                                    boxstyle='round,pad=0.005,rounding_size=0.015',
                                    fc='#f4f6fa', ec='#333333', lw=1.2))
        ax.text(x, y + 0.013, name, ha='center', va='center', fontsize=11, weight='bold',
                family='monospace')
        ax.text(x, y - 0.022, sub, ha='center', va='center', fontsize=8.5, color='#444444')
    for src, dst, label, kind, rad, at in EDGES:
        colour, style, _ = KINDS[kind]
        a = edge_point(NODES[src][:2], NODES[dst][:2])
        b = edge_point(NODES[dst][:2], NODES[src][:2])
        ax.annotate('', xy=b, xytext=a,
                    arrowprops=dict(arrowstyle='-|>', color=colour, lw=1.6, ls=style,
                                    connectionstyle='arc3,rad=%g' % rad, mutation_scale=14))
        lx, ly = a[0] + (b[0] - a[0]) * at, a[1] + (b[1] - a[1]) * at
        if rad:
            lx += -(b[1] - a[1]) * rad * 0.5
            ly += (b[0] - a[0]) * rad * 0.5
        ax.text(lx, ly, label, ha='center', va='center', fontsize=8.5, color=colour,
                family='monospace', bbox=dict(fc='white', ec='none', pad=1.0, alpha=0.9))
    # the lockstep loop: the simulator and its participants
    ax.text(0.5, -0.045, 'lockstep: /sim/lockstep/tick from the simulator, /sim/lockstep/ack from '
            'tiago_controller, corridor_controller, move_base and localisation (see lockstep.md)',
            ha='center', va='center', fontsize=8.5, color=KINDS['lockstep'][0])
    handles = [plt.Line2D([], [], color=c, ls=s, lw=2, label=l) for c, s, l in KINDS.values()
               if l != 'lockstep tick / ack']
    ax.legend(handles=handles, loc='upper left', fontsize=9, frameon=False)
    ax.set_title('tiago_nav: demo.launch (every node also reads /clock; move_base, '
                 'corridor_controller and tiago_controller read /scan and tf)', fontsize=10)
    fig.tight_layout()
    fig.savefig(out)
    print('wrote', out)


if __name__ == '__main__':
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', default=os.path.join(HERE, 'graph.png'))
    draw(ap.parse_args().out)
