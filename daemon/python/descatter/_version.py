"""The version of the package: the project's (CMakeLists.txt `project(descatter VERSION ...)`).
A plain constant so that the package installs without CMake (pyproject.toml reads it); the
test python/venv-install fails when the two differ."""
__version__ = "0.2.0"
