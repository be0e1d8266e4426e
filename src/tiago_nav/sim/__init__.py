"""The mock TIAGo: world files, the pybullet scene, the laser, the base and the map."""
