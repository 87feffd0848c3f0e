"""Oriented boxes as plain floats: the simulator calls these a few thousand times per run."""

from __future__ import annotations

import math

Point = tuple[float, float]
Box = tuple[Point, Point, Point, Point]


def _corners(cx: float, cy: float, heading: float, length: float, width: float) -> Box:
    """Counter-clockwise corners: front-left, rear-left, rear-right, front-right."""
    c, s = math.cos(heading), math.sin(heading)
    hl, hw = length / 2, width / 2
    return (
        (cx + hl * c - hw * s, cy + hl * s + hw * c),
        (cx - hl * c - hw * s, cy - hl * s + hw * c),
        (cx - hl * c + hw * s, cy - hl * s - hw * c),
        (cx + hl * c + hw * s, cy + hl * s - hw * c),
    )


def _separated(a: Box, b: Box) -> bool:
    """Whether one of ``a``'s two edge directions separates the rectangles."""
    for (x0, y0), (x1, y1) in ((a[0], a[1]), (a[1], a[2])):
        nx, ny = y0 - y1, x1 - x0
        pa = [nx * x + ny * y for x, y in a]
        pb = [nx * x + ny * y for x, y in b]
        if max(pa) < min(pb) or max(pb) < min(pa):
            return True
    return False


def _overlap(a: Box, b: Box) -> bool:
    """Separating-axis test for two rectangles."""
    return not (_separated(a, b) or _separated(b, a))


def _segment_hits_box(p: Point, q: Point, box: Box) -> bool:
    """Whether segment ``p``-``q`` passes through the rectangle (Liang-Barsky clipping)."""
    xs, ys = [c[0] for c in box], [c[1] for c in box]
    if (
        max(p[0], q[0]) < min(xs) or min(p[0], q[0]) > max(xs)
        or max(p[1], q[1]) < min(ys) or min(p[1], q[1]) > max(ys)
    ):  # fmt: skip
        return False
    t0, t1 = 0.0, 1.0
    dx, dy = q[0] - p[0], q[1] - p[1]
    # Either winding: highway-env's polygons run clockwise, ours counter-clockwise (with
    # a clockwise box the normals below pointed inwards and nothing was ever hidden).
    (ax, ay), (bx, by), (cx2, cy2) = box[0], box[1], box[2]
    turn = 1.0 if (bx - ax) * (cy2 - by) - (by - ay) * (cx2 - bx) >= 0 else -1.0
    for i in range(4):
        (cx, cy), (ex, ey) = box[i], box[(i + 1) % 4]
        nx, ny = turn * (ey - cy), -turn * (ex - cx)  # the edge's outward normal
        denom = nx * dx + ny * dy
        num = nx * (cx - p[0]) + ny * (cy - p[1])
        if abs(denom) < 1e-12:
            if num < 0:
                return False
            continue
        t = num / denom
        if denom < 0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
        if t0 > t1:
            return False
    # Grazing an occluder's edge does not hide anything.
    return t1 - t0 > 1e-6


def _centre(box: Box) -> Point:
    return (sum(c[0] for c in box) / 4, sum(c[1] for c in box) / 4)
