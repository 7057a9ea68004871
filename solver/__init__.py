"""robosolve: solve, explain, grade and publish Robotics II exam problems."""
__version__ = "0.1.0"
