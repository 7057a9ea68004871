"""Chapter: motion control. Ask kind control_law (laws)."""
