"""Motion data model: skeletons, clips, quaternions, forward kinematics, clip operations."""
from . import quat
from .skeleton import Skeleton, SkeletonMismatchError, KNOWN_FAMILIES
from .clip import Clip
from .planar import rotate_xz
from .fk import forward_kinematics, end_site_positions
from . import ops

__all__ = ["quat", "Skeleton", "SkeletonMismatchError", "KNOWN_FAMILIES", "Clip", "rotate_xz",
           "forward_kinematics", "end_site_positions", "ops"]
