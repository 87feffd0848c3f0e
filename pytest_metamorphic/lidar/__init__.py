"""LiDAR domain code: clouds, frames, ROI, obstacles, file IO, scans, reference perception."""
