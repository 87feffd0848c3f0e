"""Faulty variants of the reference pipeline, each modelled on a real failure mechanism.

Each mutant changes one stage of :class:`~.pipeline.ReferencePerception` and is
selectable by name: ``mutant("full_cloud_ground")``. They exist to measure how well
metamorphic relations find real faults (``bench/mutation_score.py``); a relation that
kills none of them is not worth running.

==========================  =================================================================
name                        fault
==========================  =================================================================
full_cloud_ground           ground estimated from every point, not only ROI points (Apollo's
                            ``use_full_cloud: true``, the root cause of Apollo issue #3341)
full_cloud_height_cut       height cut-off taken from a percentile of the whole sweep
random_point_budget         random subsample to a point budget before the ROI filter
truncating_buffer           fixed 120,000-point buffer: later points silently dropped
voxel_budget                voxel size adapted to the sweep's point count, before the ROI
global_ground_plane         one ground plane fitted to the lowest points of the whole sweep
roi_off_by_one              ROI bitmap looked up one cell off in x
count_scaled_radius         clustering cell scaled with the sweep's point count
order_dependent_voxels      voxel filter keeping the first point of each voxel
grid_anchored_at_sweep      clustering grid anchored at the sweep's bounding box
axis_aligned_boxes          axis-aligned bounding boxes instead of MinBox
raw_point_count             small objects kept by raw point count (repeats count twice)
turned_output_frame         boxes reported in a frame turned 2 degrees about the sensor (a
                            wrong yaw extrinsic applied to the detections)
dense_min_points            objects need 40 points (a minimum cluster size tuned on a dense
                            64-beam sweep)
nearest_object_list         only the 20 nearest obstacles reported (a fixed-length object
                            list, as ADAS sensors send over CAN)
intensity_floor             returns weaker than intensity 0.05 dropped as speckle (a filter
                            tuned in clear weather)
short_range_gate            returns beyond 40 m dropped (a range gate carried over from a
                            shorter-range sensor)
repeated_range_filter       returns whose range repeats a neighbouring firing's dropped as
                            dual-return echoes (harmless at 2 mm range steps)
road_user_context           clusters of fewer than 20 points kept only within 10 m of a car,
                            pedestrian or cyclist (a clutter filter that keeps road users'
                            fragments)
blinded_sensor_monitor      nothing reported when returns within 2.5 m of the sensor come from
                            two thirds of the azimuth sectors (a blockage monitor)
sweep_seam_filter           obstacles next to a gap of > 0.5 degrees in the ROI's azimuths
                            dropped as cut by the sweep's boundary
few_lasers_filter           clusters seen by fewer than 3 lasers dropped as single-beam ghosts
constant_range_filter       clusters whose returns take at most 2 distinct ranges (mm)
                            dropped as multipath ghosts
dim_cluster_filter          clusters of mean intensity below 0.05 dropped as spray
see_through_filter          clusters spanning >= 1 degree whose returns fill < 70 % of the
                            0.2-degree bearings across them dropped as vegetation
view_yaw_correction         boxes lying across the line of sight turned to lie along it
                            (Autoware shape estimation's end-on correction, pull request #11309)
sparse_heading_flip         car boxes of < 80 returns extended to a default size from the
                            wrong edge: turned 90 degrees (pull request #11634's mechanism)
temporal_ground             ground heights of each 2 m cell averaged with the previous sweep's
                            (a smoothing left on in a per-frame detector)
long_cluster_filter         obstacles longer than 10 m dropped as walls (a size cap that also
                            drops buses and trailers: autoware_universe pull request #12738)
level_ground                the ground taken to be the plane a level sensor at 1.73 m puts it
                            at, not estimated (Autoware's ray_ground_filter ``sensor_height``:
                            autoware issue #825; ghosts on a pitching car: autoware_universe
                            issue #3673)
stale_packets               1-degree azimuth columns without a return keep the returns they
                            last held (a scan buffer not cleared where packets were lost:
                            ouster-sdk issue #300)
self_crop_margin            returns within the car's footprint grown by 1 m dropped (a
                            self-filter cut too wide: autoware_universe issue #703, pull
                            request #2864)
oversized_cluster_drop      clusters of more than 12,000 returns dropped (a cluster-size cap
                            on raw returns: autoware_core issue #1379)
near_pedestrians_unknown    pedestrians within 6 m reported as unknown (a classifier that
                            does not know people close by: autoware_universe issue #7563)
slope_capped_ground         the ground may rise from the sensor's road by 3 % of the
                            distance at most (a global slope gate: autoware_universe pull
                            requests #9297, #10666)
==========================  =================================================================
"""

from __future__ import annotations

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.mutants.ground import (
    FullCloudGround,
    FullCloudHeightCut,
    GlobalGroundPlane,
    LevelGround,
    RoiOffByOne,
    SlopeCappedGround,
)
from pytest_metamorphic.lidar.systems.perception.mutants.inputs import (
    BlindedSensorMonitor,
    IntensityFloor,
    OrderDependentVoxels,
    RandomPointBudget,
    RepeatedRangeFilter,
    ShortRangeGate,
    StalePackets,
    TruncatingBuffer,
    VoxelBudget,
)
from pytest_metamorphic.lidar.systems.perception.mutants.motion import (
    SparseHeadingFlip,
    TemporalGround,
    ViewYawCorrection,
)
from pytest_metamorphic.lidar.systems.perception.mutants.near_field import (
    NearPedestriansUnknown,
    OversizedClusterDrop,
    SelfCropMargin,
)
from pytest_metamorphic.lidar.systems.perception.mutants.object_filters import (
    ConstantRangeFilter,
    DimClusterFilter,
    FewLasersFilter,
    SeeThroughFilter,
)
from pytest_metamorphic.lidar.systems.perception.mutants.objects import (
    AxisAlignedBoxes,
    CountScaledRadius,
    DenseMinPoints,
    GridAnchoredAtSweep,
    LongClusterFilter,
    NearestObjectList,
    RawPointCount,
    RoadUserContext,
    SweepSeamFilter,
    TurnedOutputFrame,
)
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    PerceptionParams,
    ReferencePerception,
)

__all__ = ["MUTANTS", "mutant"]

MUTANTS: dict[str, type[ReferencePerception]] = {
    cls.name: cls
    for cls in (
        FullCloudGround,
        FullCloudHeightCut,
        RandomPointBudget,
        TruncatingBuffer,
        VoxelBudget,
        GlobalGroundPlane,
        RoiOffByOne,
        CountScaledRadius,
        OrderDependentVoxels,
        GridAnchoredAtSweep,
        AxisAlignedBoxes,
        RawPointCount,
        TurnedOutputFrame,
        DenseMinPoints,
        NearestObjectList,
        IntensityFloor,
        RepeatedRangeFilter,
        ShortRangeGate,
        RoadUserContext,
        BlindedSensorMonitor,
        SweepSeamFilter,
        FewLasersFilter,
        ConstantRangeFilter,
        DimClusterFilter,
        SeeThroughFilter,
        ViewYawCorrection,
        SparseHeadingFlip,
        TemporalGround,
        LongClusterFilter,
        StalePackets,
        LevelGround,
        SelfCropMargin,
        OversizedClusterDrop,
        NearPedestriansUnknown,
        SlopeCappedGround,
    )
}


def mutant(name: str, params: PerceptionParams | None = None) -> ReferencePerception:
    """The faulty pipeline called ``name`` (see the module docstring for the list)."""
    try:
        cls = MUTANTS[name]
    except (KeyError, TypeError):
        raise InvalidArgument(f"unknown mutant {name!r}; known: {sorted(MUTANTS)}") from None
    return cls(params)
