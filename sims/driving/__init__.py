"""Driving tasks: dynamic bicycle model with brush tyres (Circle, Trajectory)."""
