"""`render --camera`: where the video looks from.

`track` (default) follows the robot and the task's objects: each frame it frames the bounding
box of the points of interest (every robot body, every moving task body: free objects and
mocap goal markers, and the static fixtures near the robot's start: tables, shelves, the
kitchen) at the distance that fits the box in the field of view, from the front right; with
a large fixture near, from the azimuth (of `AROUND`) from which the fewest robot bodies are
hidden behind a fixture. Centre and distance are smoothed over frames, widening faster than
narrowing, so the camera neither shakes nor cuts an object off for long. Points farther than
`REACH` from the robot's root are left out (an object thrown away does not shrink the robot
to a speck).

`side`, `front`, `back` and `top` are fixed for an episode: they frame everything the episode's
points of interest covered, seen from that side (the robot faces +x at reset). A camera the
task's model defines (`<camera name=...>`) is allowed by its name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sirl_jax.run.errors import UsageError

VIEWS = {"track": (135.0, -15.0), "side": (90.0, -8.0), "front": (180.0, -8.0),
         "back": (0.0, -8.0), "top": (90.0, -89.0)}  # fmt: skip
"""Built-in cameras: name -> (azimuth, elevation) in degrees (MuJoCo's free camera)."""
REACH = 3.0
"""Points of interest farther than this (m, horizontally) from the robot's root are ignored."""
NEAR = 2.0
"""Static fixtures within this distance (m) of the robot's root at the first frame are framed."""
MIN_DISTANCE = 1.2
AROUND = (45.0, -45.0, 90.0, -90.0, 135.0, -135.0, 0.0, 180.0)
"""`track` with a large fixture near the robot (a table, a shelf, the kitchen: bounding radius
over `LARGE_FIXTURE` m) looks from the first of these azimuths (over the right shoulder first)
from which the fewest robot bodies are hidden behind a fixture, at `AROUND_ELEVATION`."""
AROUND_ELEVATION = -25.0
LARGE_FIXTURE = 0.25
SMOOTH_WIDEN, SMOOTH_NARROW = 0.25, 0.04  # per-frame blend towards the new framing


def allowed_cameras(model) -> list[str]:
    """The built-in names, then the model's own named cameras."""
    import mujoco

    own = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(model.ncam)]
    return list(VIEWS) + [n for n in own if n and n not in VIEWS]


def check_camera(name: str, model) -> None:
    """UsageError in one line when `name` is neither built in nor one of the model's cameras."""
    allowed = allowed_cameras(model)
    if name not in allowed:
        raise UsageError(f"--camera {name!r} is unknown; allowed: {', '.join(allowed)} (track: "
                         "follows the robot and the task's objects; the others are fixed)")


@dataclass(frozen=True)
class Interest:
    """What a camera keeps in frame: the geoms of the robot and of the moving task bodies, the
    origins of those bodies (a body without geoms, e.g. a goal marker, still counts), and the
    static fixtures (geoms welded to the world, planes and height fields excluded)."""

    root: int  # the robot's root body (its position anchors REACH and NEAR)
    bodies: np.ndarray  # [B] int body ids: the robot's and the moving task bodies
    geoms: np.ndarray  # [G] int ids of those bodies' geoms
    static: np.ndarray  # [F] int geom ids of fixtures welded to the world


def interest(model) -> Interest:
    """The points of interest of a model: the pelvis subtree (or every body when there is no
    pelvis), bodies that move (a joint or a mocap body) outside it, and static non-plane geoms."""
    import mujoco

    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    root = pelvis if pelvis >= 0 else min(1, model.nbody - 1)
    ids = np.arange(1, model.nbody)
    robot = model.body_rootid[ids] == model.body_rootid[root] if pelvis >= 0 else ids >= 0
    moving = (model.body_jntnum[ids] > 0) | (model.body_mocapid[ids] >= 0)
    bodies = ids[robot | moving]
    geoms = np.flatnonzero(np.isin(model.geom_bodyid, bodies))
    welded = model.body_weldid[model.geom_bodyid] == 0
    static = np.flatnonzero(welded & (model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE)
                            & (model.geom_type != mujoco.mjtGeom.mjGEOM_HFIELD))  # fmt: skip
    return Interest(root, bodies, geoms, static)


def fixtures_near(model, data, what: Interest) -> np.ndarray:
    """Static geoms within NEAR of the robot's root now (call on an episode's first frame)."""
    gap = np.linalg.norm(data.geom_xpos[what.static, :2] - data.xpos[what.root, :2], axis=1)
    return what.static[gap - np.minimum(model.geom_rbound[what.static], NEAR) < NEAR]


def box(model, data, what: Interest, fixtures: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(low [3], high [3]) of the points of interest now, each geom grown by its bounding
    radius (capped: 0.5 m for a moving geom, 1 m for a fixture)."""
    geoms = np.concatenate([what.geoms, fixtures])
    caps = np.concatenate([np.full(len(what.geoms), 0.5), np.full(len(fixtures), 1.0)])
    p = np.concatenate([data.xpos[what.bodies], data.geom_xpos[geoms]])
    r = np.concatenate([np.full(len(what.bodies), 0.05),
                        np.minimum(model.geom_rbound[geoms], caps)])[:, None]  # fmt: skip
    keep = np.linalg.norm(p[:, :2] - data.xpos[what.root, :2], axis=1) < REACH
    p, r = p[keep], r[keep]
    return (p - r).min(axis=0), (p + r).max(axis=0)


def fit(low: np.ndarray, high: np.ndarray, fovy_deg: float, aspect: float) -> tuple:
    """(lookat [3], distance) that fits the box's bounding sphere in the narrower field of
    view (vertical `fovy_deg`; horizontal from `aspect` = width / height), 10% margin."""
    half_v = math.radians(fovy_deg) / 2
    half = min(half_v, math.atan(math.tan(half_v) * aspect))
    radius = 0.5 * float(np.linalg.norm(high - low))
    return (low + high) / 2, max(1.1 * radius / math.sin(half), MIN_DISTANCE)


class Camera:
    """One camera for one video: `start(...)` at each episode, `view(model, data)` per frame."""

    def __init__(self, model, name: str, width: int, height: int):
        import mujoco

        check_camera(name, model)
        self.name, self.aspect = name, width / height
        self.fovy = float(model.vis.global_.fovy)
        self.what = interest(model)
        self.cam = mujoco.MjvCamera()
        if name in VIEWS:
            self.cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            self.cam.azimuth, self.cam.elevation = VIEWS[name]
        else:
            self.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            self.cam.fixedcamid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
        self.fixtures = np.zeros(0, int)
        self.state: tuple | None = None

    def start(self, model, data, pose, length: int, stride: int = 5) -> None:
        """A new episode of `length` frames; `pose(t)` puts frame t's kinematics into `data`.
        Picks the fixtures near the robot at frame 0; a fixed view frames the union of the
        boxes of every `stride`-th frame."""
        pose(0)
        self.fixtures = fixtures_near(model, data, self.what)
        self.state = None
        if self.name == "track":
            large = self.fixtures.size and model.geom_rbound[self.fixtures].max() > LARGE_FIXTURE
            self.cam.azimuth, self.cam.elevation = VIEWS["track"]
            if large:
                self.cam.azimuth = self._clearest_azimuth(model, data)
                self.cam.elevation = AROUND_ELEVATION
        if self.name == "track" or self.name not in VIEWS:
            return
        low, high = box(model, data, self.what, self.fixtures)
        for t in range(stride, length, stride):
            pose(t)
            lo, hi = box(model, data, self.what, self.fixtures)
            low, high = np.minimum(low, lo), np.maximum(high, hi)
        self.state = fit(low, high, self.fovy, self.aspect)
        self._apply()

    def _clearest_azimuth(self, model, data) -> float:
        """Of `AROUND`, the first azimuth with the fewest robot bodies behind a fixture (rays
        from the camera to each body, against the world-welded geoms only)."""
        import mujoco

        lookat, distance = fit(*box(model, data, self.what, self.fixtures), self.fovy,
                               self.aspect)  # fmt: skip
        el = math.radians(AROUND_ELEVATION)
        geomid = np.zeros(1, np.int32)
        best = (math.inf, AROUND[0])
        for az in AROUND:
            a = math.radians(az)
            forward = np.array([math.cos(el) * math.cos(a), math.cos(el) * math.sin(a),
                                math.sin(el)])  # fmt: skip
            eye = lookat - distance * forward
            hidden = 0
            for target in data.xpos[self.what.bodies]:
                hit = mujoco.mj_ray(model, data, eye, target - eye, None, 1, -1, geomid)
                hidden += 0 <= hit < 0.98 and model.body_weldid[model.geom_bodyid[geomid[0]]] == 0
            best = min(best, (hidden, az), key=lambda x: x[0])
        return best[1]

    def view(self, model, data, extra: np.ndarray | None = None):
        """The `MjvCamera` for this frame (the tracking camera moves; the others do not);
        `extra` [M, 3]: more points the tracking camera keeps in frame (goal markers)."""
        if self.name == "track":
            low, high = box(model, data, self.what, self.fixtures)
            if extra is not None and len(extra):
                low = np.minimum(low, extra.min(axis=0) - 0.1)
                high = np.maximum(high, extra.max(axis=0) + 0.1)
            lookat, distance = fit(low, high, self.fovy, self.aspect)
            if self.state is None:
                self.state = (lookat, distance)
            else:
                old_at, old_d = self.state
                a = SMOOTH_WIDEN if distance > old_d else SMOOTH_NARROW
                self.state = (old_at + SMOOTH_WIDEN * (lookat - old_at),
                              old_d + a * (distance - old_d))
            self._apply()
        return self.cam

    def _apply(self) -> None:
        lookat, distance = self.state
        self.cam.lookat[:] = lookat
        self.cam.distance = distance


__all__ = ["NEAR", "REACH", "VIEWS", "Camera", "Interest", "allowed_cameras", "box",
           "check_camera", "fit", "fixtures_near", "interest"]  # fmt: skip
