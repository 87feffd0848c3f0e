"""Judging detections: which obstacles a relation may judge, and when two are the same.

:mod:`.scope` (the obstacles a relation judges: wholly inside the ROI, seen by enough
points), :mod:`.tolerance` (profiles of what counts as the same obstacle, exact or
learned), :mod:`.equivariance` (obstacles moved by a rigid motion or a mirror),
:mod:`.evaluation` (detections against ground truth: recall, precision, visibility),
:mod:`.found` (whether an object put into a sweep was found, and with which class).
"""
