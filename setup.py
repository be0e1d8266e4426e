# Do not run by hand: catkin_python_setup() in CMakeLists.txt uses it.
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(
    packages=['tiago_nav', 'tiago_nav.sim', 'tiago_nav.nav', 'tiago_nav.detection'],
    package_dir={'': 'src'},
))
