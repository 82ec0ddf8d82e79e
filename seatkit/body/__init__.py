"""Bodies and poses: the rigged default bodies, posing by linear blend skinning, the pose library.

::

    from seatkit.body import load_rig, pose_rig, load_pose, list_poses
    rig = load_rig("default-male", mass=75.0)      # RiggedBody (or a .npz path)
    pose = load_pose("upright-sitting")            # library name, pose YAML or .bvh
    body = pose_rig(rig, pose, ground=True)        # Body; lowest vertex at y = 0
"""

from seatkit.body.anthropometry import com_ratios, segment_mass_fractions, segment_masses
from seatkit.body.poses import PoseInfo, list_poses, load_pose, load_pose_file
from seatkit.body.loading import load_rig
from seatkit.body.rig import DEFAULT_BODIES, make_rig, save_rig
from seatkit.body.skinning import forward_kinematics, pose_rig

__all__ = [
    "DEFAULT_BODIES",
    "PoseInfo",
    "com_ratios",
    "forward_kinematics",
    "list_poses",
    "load_pose",
    "load_pose_file",
    "load_rig",
    "make_rig",
    "pose_rig",
    "save_rig",
    "segment_mass_fractions",
    "segment_masses",
]
