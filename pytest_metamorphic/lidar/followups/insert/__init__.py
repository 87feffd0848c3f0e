"""Scene edits: a real object placed into another sweep, as that sweep's sensor would see it.

semLidarFuzz's *add* and MultiTest's insertion, without a renderer of our own models:

1. :meth:`ObjectTemplate.from_frame` takes a labelled (or detected) object's returns from
   a real or rendered sweep and meshes them the way the sensor saw them: a Delaunay
   triangulation in (azimuth, elevation), neighbouring returns joined, holes (more than
   three beam spacings, or 1 m in depth) left open. The mesh is kept in the object's own
   coordinates, standing on its local ground, with the *view*: its heading relative to the
   line of sight.
2. :func:`free_placements` lists where it may go in another frame: on free ground (no
   return above the local ground in its footprint grown by 0.5 m), judged by the scope
   (inside the ROI), at the range it was seen from or up to 20 % nearer / 50 % farther,
   turned about the sensor so that the sensor sees the same face (the view is kept).
3. :meth:`InsertObject.onto` casts the target sensor's beams (its
   :class:`~pytest_metamorphic.lidar.model.sensors.BeamLayout`) at the placed mesh: one return
   per beam that hits it, at the hit's range and the surrounding returns' intensity, with
   the beam's ring; returns of the target that the object hides (their ray crosses the
   mesh first) go; beams whose ray meets a target return in front of the object first are
   not added. Density therefore follows the new range and the target's beams, not the
   source's.

:class:`InsertObject` is :class:`~pytest_metamorphic.core.perturbation.Reducible` over its
returns (each with the target returns it hides): a violation reduces to the fewest
inserted returns that still fail. :class:`InsertedDetected` checks that the inserted
object is found, :class:`~pytest_metamorphic.lidar.followups.edit.OthersKept` that nothing else is
lost.

Besides a recording's own labels, insertion draws the built-in rendered road users of
every size class, a child to an articulated lorry, and an adult, a cyclist and a car seen
from 4-7 m for recordings that see ground only close by
(:func:`~pytest_metamorphic.lidar.followups.insert.catalogue.road_user_templates`), and
scales templates within real class sizes
(:data:`~pytest_metamorphic.lidar.followups.insert.catalogue.CLASS_SIZES`): a recording
without labels still gets objects to insert. Templates of your own come from any
labelled recording or rendered scene (:func:`object_templates`), kept as a library
(:func:`save_templates`, :func:`load_templates`) and passed as ``objects=``; they are
re-cast for each target frame's sensor
(:func:`~pytest_metamorphic.lidar.model.sensors.frame_sensor`).
:mod:`.relocation` moves an object within its own sweep (removed where it stood, re-cast
where it goes), :class:`~.relocated.RelocatedFound` judges it.
"""

from pytest_metamorphic.lidar.followups.insert.check import InsertedDetected
from pytest_metamorphic.lidar.followups.insert.insertion import INSERTED_INSTANCE, InsertObject
from pytest_metamorphic.lidar.followups.insert.library import load_templates, save_templates
from pytest_metamorphic.lidar.followups.insert.placement import RANGE_FACTORS, free_placements
from pytest_metamorphic.lidar.followups.insert.template import (
    ObjectTemplate,
    Placement,
    object_templates,
)

__all__ = [
    "INSERTED_INSTANCE",
    "RANGE_FACTORS",
    "InsertObject",
    "InsertedDetected",
    "ObjectTemplate",
    "Placement",
    "free_placements",
    "load_templates",
    "object_templates",
    "save_templates",
]
