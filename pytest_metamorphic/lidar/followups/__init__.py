"""Follow-up inputs: how a source frame is changed, and how a violating change is reduced.

:mod:`.perturb` (points added outside or inside the ROI, dropped, duplicated, moved;
rigid motions), :mod:`.faults` (sensor faults: lost packets and rings, range
quantisation), :mod:`.weather` (fog, rain, snow), :mod:`.symmetry` (mirrors and shifts),
:mod:`.edit` (an obstacle removed), :mod:`.insert` (an obstacle inserted, or moved within
its sweep: :mod:`.insert.relocation`), :mod:`.history` (earlier sweeps a per-frame system
runs on before the source again), and :mod:`.minimize` (a violating follow-up reduced to a
minimal set of points or edits).
"""
