"""Chapter: kinematics and redundancy. Ask kind redundancy."""
