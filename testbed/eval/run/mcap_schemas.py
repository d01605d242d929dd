"""JSON Schemas of run.mcap's channels: Foxglove's well-known message schemas (named, structured and typed as
in Foxglove's public schema definitions, limited to the fields the recording writes) and the testbed's own
time-series messages. Foxglove recognises the well-known ones by their `foxglove.*` schema name."""

from __future__ import annotations

from typing import Any

Schema = dict[str, Any]


def _obj(title: str, description: str, **properties: Schema) -> Schema:
    return {"title": title, "description": description, "type": "object", "properties": properties}


def _num(description: str) -> Schema:
    return {"type": "number", "description": description}


def _time(description: str) -> Schema:
    return {"type": "object", "title": "time", "description": description, "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}}


def _vector3(description: str) -> Schema:
    return _obj("foxglove.Vector3", description, x=_num("x coordinate length"), y=_num("y coordinate length"),
                z=_num("z coordinate length"))


def _pose(description: str) -> Schema:
    quaternion = _obj("foxglove.Quaternion", "Quaternion denoting orientation in 3D space", x=_num("x value"),
                      y=_num("y value"), z=_num("z value"), w=_num("w value"))
    return _obj("foxglove.Pose", description, position=_vector3("Point denoting position in 3D space"),
                orientation=quaternion)


def _color(description: str) -> Schema:
    return _obj("foxglove.Color", description, r=_num("Red value between 0 and 1"),
                g=_num("Green value between 0 and 1"), b=_num("Blue value between 0 and 1"),
                a=_num("Alpha value between 0 and 1"))


def _string(description: str) -> Schema:
    return {"type": "string", "description": description}


def _nullable_number(description: str) -> Schema:
    return {"type": ["number", "null"], "description": description}


COMPRESSED_IMAGE = _obj(
    "foxglove.CompressedImage", "A compressed image",
    timestamp=_time("Timestamp of image"),
    frame_id=_string("Frame of reference for the image"),
    data={"type": "string", "contentEncoding": "base64", "description": "Compressed image data"},
    format=_string("Image format"),
)

POSE_IN_FRAME = _obj(
    "foxglove.PoseInFrame", "A timestamped pose for an object or reference frame in 3D space",
    timestamp=_time("Timestamp of pose"),
    frame_id=_string("Frame of reference for pose position and orientation"),
    pose=_pose("Pose in 3D space"),
)

POSES_IN_FRAME = _obj(
    "foxglove.PosesInFrame", "An array of timestamped poses for an object or reference frame in 3D space",
    timestamp=_time("Timestamp of pose"),
    frame_id=_string("Frame of reference for pose position and orientation"),
    poses={"type": "array", "description": "Poses in 3D space", "items": _pose("Pose in 3D space")},
)

LINE_PRIMITIVE = _obj(
    "foxglove.LinePrimitive", "A primitive representing a series of points connected by lines",
    type={"title": "foxglove.LineType", "description": "Drawing primitive to use for lines", "oneOf": [
        {"title": "LINE_STRIP", "const": 0, "description": "Connected line segments: 0-1, 1-2, ..., (n-1)-n"},
        {"title": "LINE_LOOP", "const": 1, "description": "Closed polygon: 0-1, 1-2, ..., (n-1)-n, n-0"},
        {"title": "LINE_LIST", "const": 2, "description": "Individual line segments: 0-1, 2-3, 4-5, ..."}]},
    pose=_pose("Origin of lines relative to reference frame"),
    thickness=_num("Line thickness"),
    scale_invariant={"type": "boolean", "description": "Indicates whether `thickness` is a fixed size in screen "
                     "pixels (true), or specified in world coordinates and scales with distance from the camera "
                     "(false)"},
    points={"type": "array", "description": "Points along the line", "items": _obj(
        "foxglove.Point3", "A point representing a position in 3D space", x=_num("x coordinate position"),
        y=_num("y coordinate position"), z=_num("z coordinate position"))},
    color=_color("Solid color to use for the whole line."),
)

SCENE_UPDATE = _obj(
    "foxglove.SceneUpdate", "An update to the entities displayed in a 3D scene",
    deletions={"type": "array", "description": "Scene entities to delete", "items": _obj(
        "foxglove.SceneEntityDeletion", "Command to remove previously published entities",
        timestamp=_time("Timestamp of the deletion"),
        type={"title": "foxglove.SceneEntityDeletionType", "description": "Type of deletion action to perform",
              "oneOf": [{"title": "MATCHING_ID", "const": 0}, {"title": "ALL", "const": 1}]},
        id=_string("Identifier which must match if `type` is `MATCHING_ID`."))},
    entities={"type": "array", "description": "Scene entities to add or replace", "items": _obj(
        "foxglove.SceneEntity", "A visual element in a 3D scene",
        timestamp=_time("Timestamp of the entity"),
        frame_id=_string("Frame of reference"),
        id=_string("Identifier for the entity; replaces any prior entity on the same topic with the same id"),
        lifetime={"type": "object", "title": "duration", "description": "Time after which the entity is "
                  "removed; zero keeps it until it is replaced or deleted", "properties": {
                      "sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0,
                                                           "maximum": 999_999_999}}},
        frame_locked={"type": "boolean", "description": "Whether the entity follows `frame_id` as it moves "
                      "relative to the fixed frame"},
        lines={"type": "array", "description": "Line primitives", "items": LINE_PRIMITIVE})},
)

SIGNALS = _obj(
    "ld3.Signals", "One control tick of the detection and response loop (null: no value, as in trajectory.csv)",
    t=_num("simulated time (s)"),
    phys_dev=_nullable_number("physical lateral deviation D of the true pose (m, + left)"),
    msf_dev=_nullable_number("D of the localization output, D_MSF (m)"),
    ld_dev=_nullable_number("D from the latest lane detection, D_LD (m)"),
    fused_dev=_nullable_number("the fused deviation d in attack response (m)"),
    cusum=_nullable_number("the defense's detection statistic (m)"),
    tau=_nullable_number("the threshold the statistic alarms above, τ (m)"),
    mode=_string("normal, or ar once the defense responds"),
    ar={"type": "integer", "description": "1 in attack response, else 0 (for plots)"},
    speed=_num("measured speed (m/s)"),
    steer=_num("road-wheel steering command (rad, + left)"),
    accel=_num("longitudinal command (m/s²)"),
)

ATTACK = _obj(
    "ld3.Attack", "The attack's state at one control tick",
    t=_num("simulated time (s)"),
    stage=_string("the attack's stage (idle, profiling, aggressive, active, ...)"),
    offset=_nullable_number("the attack's current lateral offset (m, + left)"),
)

CAN_FRAME = _obj(
    "ld3.CanFrame", "One CAN frame with the signals its DBC message decodes to",
    t=_num("simulated time (s)"),
    id={"type": "integer", "description": "arbitration id"},
    data=_string("payload bytes as hex"),
    signals={"type": "object", "description": "decoded signals by DBC name (numbers; enum choices as strings)",
             "additionalProperties": {"type": ["number", "string"]}},
)

_CUBIC = {"type": ["array", "null"], "items": {"type": "number"}, "minItems": 4, "maxItems": 4,
          "description": "y(x) = c0 + c1 x + c2 x² + c3 x³ in the vehicle frame (m), null: no line"}

LD3_INPUT = _obj(
    "ld3.Ld3Input", "What LD3's detection read at one camera frame: the lane detection and the localization estimate",
    t=_num("simulated time of the frame (s)"),
    detection=_obj("ld3.LaneDetection", "the lane detection handed to the defense", left=_CUBIC, right=_CUBIC,
                   left_prob=_num("left line existence probability"), right_prob=_num("right line existence "
                                                                                     "probability"),
                   x_range={"type": "array", "items": {"type": "number"}, "description": "valid x range (m)"},
                   left_var=_nullable_number("c0 variance of the left line (m²)"),
                   right_var=_nullable_number("c0 variance of the right line (m²)")),
    msf=_obj("ld3.LocalizationEstimate", "the localization estimate paired with it (after any MSF-side attack)",
             t=_num("estimate time (s)"), x=_num("world x (m)"), y=_num("world y (m)"), yaw=_num("yaw (rad)"),
             cov={"type": "array", "items": {"type": "number"}, "description": "3×3 covariance of (x, y, yaw), "
                  "row-major"}),
)
