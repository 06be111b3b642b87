"""BVH (Biovision Hierarchy) motion capture import and export.

Reading turns a ``.bvh`` file into a runtime :class:`~runtime.motion.clip.Clip` (root
position in metres, joint local rotations as unit quaternions, world placement of frame 0
kept in ``clip.origin``); writing does the reverse. No paper equation is implemented here;
the format follows the Biovision description as written by the CMU/cgspeed releases
(../shared/mocap/cmu/README.md lists their quirks, all handled here).

Modules:

* :mod:`.parse`: text to numbers (hierarchy, MOTION header, frame block) and
  :class:`BVHError` (``"path:LINE: what is wrong"``);
* :mod:`.families`: file units by skeleton family, synthetic first frames, frame rates;
* :mod:`.read`: :func:`read_bvh` (channel orders to quaternions, scale, dropping a
  synthetic first frame, resampling) and :func:`bvh_summary` (for ``crowdweave info``);
* :mod:`.write`: :func:`bvh_text` and :func:`write_bvh`.
"""
from .families import FAMILY_SCALES, T0_MIN_DEGREES, T0_RATIO, default_scale
from .parse import MAX_ABS_VALUE, BVHError
from .read import BVHMotion, bvh_summary, read_bvh
from .write import bvh_text, write_bvh

__all__ = ["BVHError", "BVHMotion", "read_bvh", "write_bvh", "bvh_text", "bvh_summary",
           "FAMILY_SCALES", "default_scale", "MAX_ABS_VALUE", "T0_MIN_DEGREES", "T0_RATIO"]
