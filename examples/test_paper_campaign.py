"""Zhou & Sun's MR1 campaign (CACM 2019), reproduced on synthetic HDL-64E scenes.

The paper added 10, 100 and 1000 random points *outside* the HD-map ROI of 1000 real
Velodyne frames and counted how often Apollo's obstacle list then shrank: 2.7%, 12.1%
and 33.5% of the follow-ups. This file runs the same protocol (independent random
sources, one follow-up per source and noise size, the system run once per source) on
street scenes the project renders with the real HDL-64E beam layout, so it needs no data:

* the reference pipeline, which filters by ROI first: no follow-up may lose an obstacle,
  and one that does fails the test (the campaign's default gate);
* the same pipeline with one realistic fault, a clustering cell that grows with the
  sweep's point count (``count_scaled_radius``): points far outside the ROI change how
  obstacles inside it are grouped, and the violation rate grows with n as in the paper.
  Its test *expects* violations (``expect_violations=True``): it passes, saying how many
  it found, and would fail if the relation stopped detecting the fault.

Run it (add ``-n 2`` to spread the sources over two processes; the result is identical)::

    pytest examples/test_paper_campaign.py --mt-campaign

The table and each campaign's gate print at the end of the run; JSON, Markdown and a
PNG chart (violation rates with their intervals beside the paper's Fig. 3) are written
under ``mt-campaigns/``, and the first violations of each size are saved as replayable
artifacts under ``mt-artifacts/``. To test your own stack, replace ``system`` with a
function ``Frame -> list[Box]`` calling it; to gate on a rate rather than on any
violation, give ``campaign_test(..., max_rate=0.05)``, and to gate on main's rate, run
with ``--mt-baseline <main's mt-campaigns folder>`` (docs/ci.md).
"""

from __future__ import annotations

from typing import Final

from pytest_metamorphic.core.campaign import campaign_test
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.lidar.systems.perception.pipeline import ReferencePerception

SOURCES = 200  # the paper used 1000 frames; bench/campaign.py runs the full protocol
# Apollo and the reference pipeline filter by ROI first: everything they report is on the
# road, so every obstacle is judged, as in the paper. A detector that reports the whole
# sweep keeps the default scope (obstacles wholly inside the ROI); see the README.
SCOPE: Final = "all"

reference = ReferencePerception()
faulty = mutant("count_scaled_radius")


def reference_system(frame: Frame) -> list[Box]:
    return reference(frame.cloud, frame.roi)


def faulty_system(frame: Frame) -> list[Box]:
    return faulty(frame.cloud, frame.roi)


test_mr1_reference = campaign_test(
    mr1_campaign(reference_system, name="MR1 reference pipeline", sources=SOURCES, scope=SCOPE)
)
test_mr1_count_scaled_radius = campaign_test(
    mr1_campaign(
        faulty_system, name="MR1 mutant count_scaled_radius", sources=SOURCES, scope=SCOPE
    ),
    expect_violations=True,  # a known fault: the relation must detect it
)
