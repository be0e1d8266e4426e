"""``python3 -m tiago_nav_tools.testing.realdata LOG OUT_DIR [--scenarios tracking,kidnap] [--seed N]
[--no-bags]``: a CARMEN log converted into a map (map_server YAML + PGM), per scenario a bag
(needs ROS's rosbag) and its reference (see :mod:`tiago_nav_tools.testing.realdata.convert`)."""
import argparse
import json
import sys

from tiago_nav_tools.testing.realdata.carmen import LogError
from tiago_nav_tools.testing.realdata.convert import SCENARIOS, SEED, prepare


def main(argv=None):
    ap = argparse.ArgumentParser(prog='python3 -m tiago_nav_tools.testing.realdata',
                                 description=__doc__.split('\n\n')[0])
    ap.add_argument('log', help='CARMEN log (.log or .log.gz)')
    ap.add_argument('out_dir')
    ap.add_argument('--scenarios', default=','.join(SCENARIOS),
                    help='comma-separated, of: %s' % ', '.join(SCENARIOS))
    ap.add_argument('--seed', type=int, default=SEED, help='of the odometry noise')
    ap.add_argument('--no-bags', action='store_true', help='map and references only (no ROS)')
    a = ap.parse_args(argv)
    try:
        out = prepare(a.log, a.out_dir, [s for s in a.scenarios.split(',') if s], a.seed,
                      bags=not a.no_bags)
    except (OSError, LogError, ValueError) as e:
        print('realdata: %s' % e, file=sys.stderr)
        return 2
    print(json.dumps(out, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
