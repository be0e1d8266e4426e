"""Makes the library importable from the source tree (no ROS master needed). The generated
message modules (``tiago_nav.msg``, ``tiago_nav.srv``) live in the catkin workspace's devel space:
when it has been built, they are joined to the package so the node modules import too."""
import glob
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, 'src'))
for sp in sorted(glob.glob(os.path.join(ROOT, '.venv', 'lib', 'python3*', 'site-packages'))):
    if sp not in sys.path:
        sys.path.append(sp)
import tiago_nav  # noqa: E402

for d in glob.glob(os.path.join(ROOT, '.ws', 'devel', 'lib', 'python3*', 'dist-packages', 'tiago_nav')):
    if d not in tiago_nav.__path__:
        tiago_nav.__path__.append(d)
WORLDS = os.path.join(ROOT, 'worlds')
