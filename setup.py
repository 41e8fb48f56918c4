# The Python package (python/deformable_flsm), installed by catkin (catkin_python_setup()); the
# compiled bindings (_core) are built by CMake into the same package.
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(packages=["deformable_flsm"], package_dir={"": "python"}))
