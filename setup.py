# Do not run by hand: catkin_python_setup() in CMakeLists.txt uses it.
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(
    packages=['tiago_nav', 'tiago_nav.corridor', 'tiago_nav.detection', 'tiago_nav.localisation',
              'tiago_nav.mission', 'tiago_nav.nav', 'tiago_nav.nodes', 'tiago_nav.ros',
              'tiago_nav.sim',
              'tiago_nav_tools', 'tiago_nav_tools.evaluate', 'tiago_nav_tools.testing',
              'tiago_nav_tools.testing.realdata'],
    package_dir={'': 'src'},
))
