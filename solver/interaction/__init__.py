"""Chapter: interaction with the environment (constraints, force control, collisions)."""
