"""What the browser draws versus what the kinematics computes: shared by the drawing tests.

viser keeps, for every scene node, the last pose it sent to the browsers (``server.scene._handle_from_node_name``,
each handle's ``.position`` and ``.wxyz`` relative to its parent node). Composing them along a node's path gives
the world pose every browser draws for it; :func:`fk_link_poses` gives the same for every URDF link from
pinocchio's forward kinematics.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from studio.core.kinematics import Baxter, matrix_from_quat_wxyz
from studio.core.types import ALL_ARM_JOINTS

#: Finger travel (m) of the electric gripper, 100 % open (the URDF's prismatic limit).
FINGER_TRAVEL = 0.020833


def drawn_node_poses(server, root: str = "/robot/visual", base_link: str = "base") -> dict[str, np.ndarray]:
    """World transforms (4, 4) of every scene node under ``root``, keyed by the node's last name component
    (``root`` itself is the URDF's root link ``base_link``).

    Nodes missing from the registry (none are expected) count as identity, as in the browser.
    """
    handles = dict(server.scene._handle_from_node_name)
    cache: dict[str, np.ndarray] = {}

    def world(name: str) -> np.ndarray:
        if name in ("", "/"):
            return np.eye(4)
        if name in cache:
            return cache[name]
        parent = name.rsplit("/", 1)[0]
        T_parent = world(parent)
        h = handles.get(name)
        T = np.eye(4)
        if h is not None:
            T[:3, :3] = matrix_from_quat_wxyz(np.asarray(h.wxyz, dtype=np.float64))
            T[:3, 3] = np.asarray(h.position, dtype=np.float64)
        cache[name] = out = T_parent @ T
        return out

    out = {}
    for name in handles:
        if name == root:
            out[base_link] = world(name)
        elif name.startswith(root + "/"):
            out[name.rsplit("/", 1)[1]] = world(name)
    return out


def full_configuration(baxter: Baxter, q14: np.ndarray, gripper2: np.ndarray, head: float = 0.0) -> np.ndarray:
    """pinocchio's 19-value configuration for arm joints (14,) rad and grippers (2,) percent open."""
    model = baxter.model
    q = pin.neutral(model)

    def put(joint: str, value: float) -> None:
        q[model.joints[model.getJointId(joint)].idx_q] = value

    put("head_pan", head)
    for name, v in zip(ALL_ARM_JOINTS, q14, strict=True):
        put(name, float(v))
    for side, g in zip("lr", gripper2, strict=True):
        travel = float(np.clip(g, 0.0, 100.0)) / 100.0 * FINGER_TRAVEL
        put(f"{side}_gripper_l_finger_joint", travel)
        put(f"{side}_gripper_r_finger_joint", -travel)  # the URDF's mimic joint (multiplier −1)
    return q


def fk_link_poses(baxter: Baxter, q14: np.ndarray, gripper2: np.ndarray) -> dict[str, np.ndarray]:
    """World transforms (4, 4) of every URDF link (pinocchio body frames) for the given configuration."""
    model = baxter.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, full_configuration(baxter, q14, gripper2))
    out = {}
    for fid, frame in enumerate(model.frames):
        if frame.type == pin.FrameType.BODY:
            out[frame.name] = np.asarray(data.oMf[fid].homogeneous).copy()
    return out


def pose_errors(drawn: dict[str, np.ndarray], fk: dict[str, np.ndarray]) -> dict[str, tuple[float, float]]:
    """Per link: (position error m, rotation error rad) between the drawn and the computed pose."""
    out = {}
    for link, T in fk.items():
        if link not in drawn:
            continue
        D = drawn[link]
        dp = float(np.linalg.norm(D[:3, 3] - T[:3, 3]))
        c = (np.trace(D[:3, :3].T @ T[:3, :3]) - 1.0) / 2.0
        out[link] = (dp, float(np.arccos(np.clip(c, -1.0, 1.0))))
    return out
