"""Chapter: motion planning (trajectories, time scaling)."""
