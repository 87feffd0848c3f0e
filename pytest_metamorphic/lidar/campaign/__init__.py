"""LiDAR relations as campaigns: violation rates with Wilson intervals, per size or severity.

- :func:`mr1_campaign` (:mod:`.paper`): the paper's MR1 protocol (Zhou & Sun, CACM 2019,
  section "Results").
- :func:`fault_campaign` (:mod:`.faults`): dead lasers, lost packets, fog, rain, range
  quantisation, per severity.
- :func:`edit_campaign` (:mod:`.edits`): object insertion (per range) and removal (per
  object, nearest first).
- :func:`symmetry_campaign` (:mod:`.symmetry`): rotation (per angle), the mirror, and
  translation (per shift).

Sources are rendered street scenes (:func:`synthetic_frames`, no data needed) or
recorded frames with an ROI (:func:`recorded_frames`, e.g. the KITTI sweeps with the
camera wedge).

Examples
--------
>>> from pytest_metamorphic.core.campaign import campaign_test
>>> from pytest_metamorphic.lidar.campaign import mr1_campaign
>>> test_mr1 = campaign_test(mr1_campaign(my_perception, name="MR1 my stack"))  # doctest: +SKIP

and run ``pytest --mt-campaign``.
"""

from __future__ import annotations

from pytest_metamorphic.lidar.campaign.edits import (
    EDIT_SEVERITIES,
    edit_campaign,
    insertion_followup,
    removal_followup,
)
from pytest_metamorphic.lidar.campaign.faults import (
    FAULT_SEVERITIES,
    dead_beams_followup,
    fault_campaign,
    fog_followup,
    lost_packets_followup,
    quantized_followup,
    rain_followup,
)
from pytest_metamorphic.lidar.campaign.paper import mr1_campaign, noise_followup
from pytest_metamorphic.lidar.campaign.sources import (
    DEFAULT_SYNTHETIC_SOURCES,
    SourceFn,
    box_label,
    recorded_frames,
    synthetic_frames,
)
from pytest_metamorphic.lidar.campaign.symmetry import (
    SYMMETRY_SEVERITIES,
    mirrored_followup,
    shifted_followup,
    symmetry_campaign,
    turned_followup,
)

__all__ = [
    "DEFAULT_SYNTHETIC_SOURCES",
    "EDIT_SEVERITIES",
    "FAULT_SEVERITIES",
    "SYMMETRY_SEVERITIES",
    "SourceFn",
    "box_label",
    "dead_beams_followup",
    "edit_campaign",
    "fault_campaign",
    "fog_followup",
    "insertion_followup",
    "lost_packets_followup",
    "mirrored_followup",
    "mr1_campaign",
    "noise_followup",
    "quantized_followup",
    "rain_followup",
    "recorded_frames",
    "removal_followup",
    "shifted_followup",
    "symmetry_campaign",
    "synthetic_frames",
    "turned_followup",
]
