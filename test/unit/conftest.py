"""Makes the library importable from the source tree (no workspace or ROS master needed)."""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, 'src'))
for sp in sorted(__import__('glob').glob(os.path.join(ROOT, '.venv', 'lib', 'python3*', 'site-packages'))):
    if sp not in sys.path:
        sys.path.append(sp)
WORLDS = os.path.join(ROOT, 'worlds')
