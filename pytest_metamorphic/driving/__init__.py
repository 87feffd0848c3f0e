"""Driving domain code: Euro NCAP AEB scenarios, OSM roads, kinematics, AEB controllers."""
