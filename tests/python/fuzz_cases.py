"""Seeded mutations of valid pickplan inputs and the code that runs one case (used by test_fuzz.py).

Run as a worker: ``python fuzz_cases.py CASES.json`` reads [{"kind", "payload"}, ...] and prints,
per case, ``BEGIN i`` before and one JSON line after, so the parent can attribute a crash or a hang
to the case that caused it. Allowed outcomes: a valid result with finite numbers, or a documented
error (ValueError, of which InputError, FileNotFoundError): anything else is a finding."""

from __future__ import annotations

import base64
import copy
import json
import os
import random
import sys
import tempfile

import numpy as np

ALLOWED_ERRORS = (ValueError, FileNotFoundError)
WEIRD_NUMBERS = ["NaN", "Infinity", "-Infinity", "-1", "0", "1e308", "-1e308", "4294967299", "1e-320", "3"]
TOML_NUMBERS = [
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-300",
    "0",
    "-1",
    "0.0",
    "9" * 5000,
    '"x"',
    "[]",
    "{}",
    "true",
    "[1e308, 1e308]",
]
HUGE_INTEGER = "9" * 5000  # more digits than Python converts to int from text (4,300)
WEIRD_VALUES = [
    float("nan"),
    float("inf"),
    -1.0,
    0.0,
    1e308,
    2**32 + 3,
    -(2**63),
    "1.0",
    "",
    None,
    True,
    [],
    {},
    [[1, 2], [3]],
    "\u0000",
]


# --- mutation -------------------------------------------------------------------------------------
def _leaves(obj, path=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _leaves(v, path + (i,))
    yield path


def _set(obj, path, value):
    for p in path[:-1]:
        obj = obj[p]
    obj[path[-1]] = value


def _get(obj, path):
    for p in path:
        obj = obj[p]
    return obj


def mutate_json(data, rng: random.Random) -> str:
    """One to three structural mutations of a JSON document, or a text-level one."""
    if rng.random() < 0.25:
        return mutate_text(json.dumps(data), rng)
    data = json.loads(json.dumps(data))
    for _ in range(rng.randint(1, 3)):
        paths = [p for p in _leaves(data) if p]
        if not paths:
            break
        path = rng.choice(paths)
        op = rng.random()
        parent = _get(data, path[:-1])
        if op < 0.45:  # a copy: the shared list must not end up inside itself, nor change for later cases
            _set(data, path, copy.deepcopy(rng.choice(WEIRD_VALUES)))
        elif op < 0.6:
            if isinstance(parent, dict):
                del parent[path[-1]]
            else:
                parent.pop(path[-1])
        elif op < 0.7:
            value = _get(data, path)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                _set(data, path, value * rng.choice([-1, 1e-9, 1e9, 1 + 1e-6, 1.5]))
        elif op < 0.8:
            _set(data, path, [copy.deepcopy(_get(data, path)) for _ in range(rng.randint(0, 3))])
        elif op < 0.9:  # deep nesting, spliced in as text (json.dumps itself recurses)
            _set(data, path, f"__NEST_{rng.choice([10, 1000, 50_000])}__")
        else:
            value = _get(data, path)
            _set(data, path, str(value) if not isinstance(value, str) else 12345)
    text = json.dumps(data, allow_nan=True)
    for depth in (10, 1000, 50_000):
        text = text.replace(f'"__NEST_{depth}__"', "[" * depth + "0" + "]" * depth)
    return text if rng.random() < 0.95 else text[: -rng.randint(1, 20)]


def replace_numbers(text: str, rng: random.Random, choices, times: int = 1) -> str:
    """``times`` numbers of ``text`` replaced by values drawn from ``choices``."""
    import re

    for _ in range(times):
        spans = [m.span() for m in re.finditer(r"-?\d+(\.\d+)?(e-?\d+)?", text)]
        if not spans:
            break
        a, b = rng.choice(spans)
        text = text[:a] + rng.choice(choices) + text[b:]
    return text


def mutate_toml(text: str, rng: random.Random) -> str:
    """A robot description with weird numbers, names swapped for others of the file, or text damage."""
    import re

    op = rng.random()
    if op < 0.45:
        return replace_numbers(text, rng, TOML_NUMBERS, rng.randint(1, 3))
    if op < 0.7:
        names = re.findall(r'"([A-Za-z0-9_]+)"', text)
        for _ in range(rng.randint(1, 2)):
            a, b = rng.choice(names), rng.choice(names + ["nothing", "", "table"])
            text = text.replace(f'"{a}"', f'"{b}"', 1)
        return text
    if op < 0.8:  # a line dropped: a missing key or table
        lines = text.splitlines()
        del lines[rng.randrange(len(lines))]
        return "\n".join(lines)
    return mutate_text(text, rng)


def mutate_observation(fields: dict, rng: random.Random) -> bytes:
    """An observation archive (.npz bytes) with one to three arrays changed, or its bytes damaged."""
    import io

    arrays = {k: np.array(v, copy=True) for k, v in fields.items()}
    for _ in range(rng.randint(1, 3)):
        key = rng.choice(sorted(arrays))
        a = arrays[key]
        op = rng.random()
        if op < 0.35 and a.size and a.dtype.kind in "fiub":
            a = a.astype(float) if rng.random() < 0.5 else a
            idx = tuple(rng.randrange(n) for n in a.shape)
            value = rng.choice([np.nan, np.inf, -1.0, 0.0, 1e-300, 1e308, -1e308, 2.0, 1e9])
            try:
                a[idx] = value
            except (OverflowError, ValueError):
                a = a.astype(float)
                a[idx] = value
        elif op < 0.5:
            dtype = rng.choice([np.float32, np.int64, np.bool_, np.complex128, np.uint8, str])
            a = a.astype(str if a.dtype.kind == "U" else dtype)  # a string array converts only to strings
        elif op < 0.6:
            a = a.reshape(-1) if rng.random() < 0.5 else a[..., : max(1, a.shape[-1] // 2)] if a.ndim else a
        elif op < 0.7:
            del arrays[key]
            continue
        elif op < 0.8:
            arrays["target_pixel"] = np.array(rng.choice([[60, 80], [[3, 4, 5]], [[-1, -1]], [[10**6, 2]], [1.5, 2]]))
            arrays.pop("target_mask", None)
            continue
        elif op < 0.9 and key in ("K", "camera_pose"):
            a = a * rng.choice([1e-300, -1.0, 1e9, 0.0])
        else:
            a = np.array(rng.choice([0, "x", 1e308]))
        arrays[key] = a
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    data = buf.getvalue()
    if rng.random() < 0.25:
        b = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        data = bytes(b[: rng.randint(0, len(b))] if rng.random() < 0.4 else b)
    return data


def mutate_text(text: str, rng: random.Random) -> str:
    op = rng.random()
    if op < 0.3:  # a number replaced by a weird one
        import re

        spans = [m.span() for m in re.finditer(r"-?\d+(\.\d+)?(e-?\d+)?", text)]
        for _ in range(rng.randint(1, 4)):
            if spans:
                a, b = rng.choice(spans)
                text = text[:a] + rng.choice(WEIRD_NUMBERS).ljust(b - a)[: max(b - a, 3)] + text[b:]
                spans = [m.span() for m in re.finditer(r"-?\d+(\.\d+)?(e-?\d+)?", text)]
        return text
    if op < 0.45:
        return text[: rng.randint(0, len(text))]
    if op < 0.6:
        i, j = sorted(rng.randint(0, len(text)) for _ in range(2))
        return text[:i] + text[j:]
    if op < 0.75:
        i, j = sorted(rng.randint(0, len(text)) for _ in range(2))
        return text[:j] + text[i:j] * rng.randint(1, 5) + text[j:]
    if op < 0.9:
        chars = list(text)
        for _ in range(rng.randint(1, 10)):
            if chars:
                chars[rng.randrange(len(chars))] = chr(
                    rng.choice([0, 10, 34, 39, 47, 60, 62, 91, 93, 123, 125, rng.randint(32, 126), 0xFFFD])
                )
        return "".join(chars)
    i = rng.randint(0, len(text))
    return text[:i] + rng.choice(["<a>" * 20_000, "[" * 20_000, "\x00\xff", "&lt;", "<!--", "]]>"]) + text[i:]


def mutate_array(arr: np.ndarray, rng: random.Random) -> bytes:
    """A mutated (N, 4, 4) grasp array as .npy bytes (sometimes corrupted bytes)."""
    import io

    a = np.array(arr, dtype=float)
    op = rng.random()
    idx = tuple(rng.randrange(s) for s in a.shape) if a.size else None
    if op < 0.15 and idx:
        a[idx] = rng.choice([np.nan, np.inf, -np.inf, 1e308])
    elif op < 0.3:
        a[..., :3, :3] *= 1 + rng.choice([1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 0.1])
    elif op < 0.4:
        a[..., 2, :3] *= -1  # a reflection
    elif op < 0.5:
        a = a.reshape(rng.choice([(-1, 16), (-1, 4, 2, 2), (-1,)]))
    elif op < 0.55:
        a = a[:0]
    elif op < 0.65:
        a = a.astype(rng.choice([np.float32, np.int64, np.complex128, np.bool_]))
    elif op < 0.7:
        a = np.array(["x"] * 3)
    elif op < 0.8 and idx:
        a[idx[0], 3] = [0, 0, 0, rng.choice([0.0, 2.0])]
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    data = buf.getvalue()
    if op >= 0.8:
        b = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        data = bytes(b[: rng.randint(0, len(b))] if rng.random() < 0.3 else b)
    return data


# --- running one case ------------------------------------------------------------------------------
def _finite(*arrays) -> None:
    for a in arrays:
        a = np.asarray(a, dtype=float)
        if not np.all(np.isfinite(a)):
            raise AssertionError("NaN or infinity in a result")


def run_scene(text: str, work: str):
    from pickplan.sim.scenes import Scene

    scene = Scene.from_json(text)
    _finite(
        scene.robot_base,
        scene.table.size,
        scene.table.pose,
        scene.robot_configuration,
        *[o.pose for o in scene.objects],
    )


def run_grasps(data_b64: str, work: str):
    from pickplan.core.objects import read_grasp_array
    from pickplan.omg import grasps as G
    import pickplan

    path = os.path.join(work, "grasps_graspit.npy")
    with open(path, "wb") as f:
        f.write(base64.b64decode(data_b64))
    poses = G.check_grasps(read_grasp_array(path), path)
    _finite(poses)
    if len(poses):  # the bindings' own rigidity check must agree with the Python one
        moved = _panda().with_base(poses[0])
        _finite(moved.base_pose)
    return pickplan


_PANDA = []


def _panda():
    if not _PANDA:
        from pickplan.core import robots

        _PANDA.append(robots.panda())
    return _PANDA[0]


def run_metamodel(text: str, work: str):
    from pickplan import _core
    from pickplan.pickup.metamodel.validate import validate_metamodel

    from pickplan.core.io import read_json

    path = os.path.join(work, "metamodel.json")
    with open(path, "w", encoding="utf-8", errors="surrogatepass") as f:
        f.write(text)
    d = validate_metamodel(read_json(path, "meta-model file"), path)
    for lv in d["levels"]:  # what the pickup NLP reads from a file (planner.load_rho)
        s = lv["surface"]
        rho = _core.RhoPoly(np.asarray(s["coeffs"], float), tuple(s["sg_range"]), tuple(s["sc_range"]))
        for sg in np.linspace(*s["sg_range"], 4):
            for sc in np.linspace(*s["sc_range"], 3):
                _finite(rho.value(float(sg), float(sc)))


def run_problem(text: str, work: str):
    """A pick-up problem file as `pickplan pickup plan` reads it, down to the native problem (the
    stand-in surface: the meta-model file kind has its own fuzzing)."""
    from pickplan.pickup.nlp import planner, problem_file

    path = os.path.join(work, "problem.json")
    with open(path, "w", encoding="utf-8", errors="surrogatepass") as f:
        f.write(text)
    spec = problem_file.load_problem(path)
    pb = problem_file.native_problem(planner.mobile_ur5(), spec, planner.synthetic_rho(spec.sigma_r, spec.sigma_phi))
    _finite(pb.start, pb.goal, pb.arm_start, pb.grasp_pose, [r for _, r in pb.obstacles])


def run_urdf(text: str, work: str):
    from pickplan.core import robots

    path = os.path.join(work, "robot.urdf")
    with open(path, "w", encoding="utf-8", errors="surrogatepass") as f:
        f.write(text)
    robot = robots.Robot.from_urdf(path)
    q = robot.random_configurations(2, seed=0)
    _finite(robot.lower_limits[np.isfinite(robot.lower_limits)], robot.fk_batch(q))
    if robot.dof:
        _finite(robot.jacobian(q[0], robot.link_names[-1]))
    body = robot.sample_body_points(per_link=3, seed=0)
    _finite(body.points, body.normals, robot.transform_points(q, body))


def run_mesh(files: dict, work: str):
    from pickplan.core import objects, sdf

    folder = os.path.join(work, "obj_fuzz")
    os.makedirs(folder, exist_ok=True)
    for name in ("mesh.stl", "collision.obj"):
        path = os.path.join(folder, name)
        if os.path.exists(path):
            os.unlink(path)
        if files.get(name) is not None:
            with open(path, "w", encoding="utf-8", errors="surrogatepass") as f:
                f.write(files[name])
    model = objects.load_ycb_object(folder)
    _finite(model.mesh.vertices, model.com, model.inertia, model.mass)
    grid = sdf.mesh_sdf(model.mesh, sdf.SdfSettings(resolution=0.02, margin=0.02, cache_dir=""))
    _finite(grid.values)


def run_robot(text: str, work: str):
    """A robot description as every command reads it: `robots check` and `load_robot` must agree
    (one path), and a robot that loads must time a motion within its limits to finite numbers."""
    from pickplan.core.robots import check_description, load_robot
    from pickplan.core.timing import robot_limits, time_parameterize

    path = os.path.join(work, "robot.toml")
    with open(path, "w", encoding="utf-8", errors="surrogatepass") as f:
        f.write(text)
    _, problems = check_description(path)
    try:
        robot = load_robot(path)
    except ValueError:
        if not problems:
            raise AssertionError("load_robot refused a file `robots check` accepts")
        raise
    if problems:
        raise AssertionError(f"load_robot accepted a file `robots check` refuses: {problems[0]}")
    q0 = robot.ready_configuration
    q1 = robot.clip_to_limits(q0 + 0.1)
    _finite(robot.fk(q0), robot.random_configurations(2, seed=0))
    timed = time_parameterize(np.stack([q0, q1]), rate=100.0, limits=robot_limits(robot))
    _finite(timed.t, timed.q, timed.qd, timed.qdd)


def run_observation(data_b64: str, work: str):
    """An observation file as `pickplan plan --observation` reads it, down to the perceived world's
    field and target points."""
    from pickplan.core.observation import Observation
    from pickplan.perception.field import FieldSettings, perceive

    path = os.path.join(work, "obs.npz")
    with open(path, "wb") as f:
        f.write(base64.b64decode(data_b64))
    obs = Observation.load(path)
    perceived = perceive(obs, FieldSettings(resolution=0.02))
    _finite(perceived.target_points, perceived.target_normals, perceived.plane[0], perceived.plane[1])


def run_exec(code: str, work: str):  # the harness's own test: a case is any Python statement
    exec(code, {})


RUNNERS = {
    "exec": run_exec,
    "scene": run_scene,
    "grasps": run_grasps,
    "metamodel": run_metamodel,
    "problem": run_problem,
    "urdf": run_urdf,
    "mesh": run_mesh,
    "robot": run_robot,
    "observation": run_observation,
}


# Kinds whose every error must name the file read (issue 39: the README's exit-code contract).
NAMED_FILES = {
    "robot": "robot.toml",
    "observation": "obs.npz",
    "problem": "problem.json",
    "metamodel": "metamodel.json",
}


def run_case(kind: str, payload, work: str) -> dict:
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            RUNNERS[kind](payload, work)
        return {"outcome": "valid"}
    except ALLOWED_ERRORS as exc:
        message = str(exc)
        if not message.strip():
            return {"outcome": "unclear", "error": f"{type(exc).__name__} without a message"}
        if kind in NAMED_FILES and os.path.join(work, NAMED_FILES[kind]) not in message:
            return {"outcome": "unnamed", "error": f"{type(exc).__name__} naming no file: {message[:200]}"}
        return {"outcome": "error", "error": f"{type(exc).__name__}: {message[:200]}"}
    except AssertionError as exc:  # NaN in a result, or two readers of one file that disagree
        return {"outcome": "bad result", "error": str(exc)}
    except Exception as exc:  # noqa: BLE001 - the finding: an undocumented exception type
        return {"outcome": "unclear", "error": f"{type(exc).__name__}: {str(exc)[:300]}"}


def main(path: str, start: int) -> None:
    with open(path) as f:
        cases = json.load(f)
    work = tempfile.mkdtemp(prefix="pickplan-fuzz-")
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 1000))
    for i in range(start, len(cases)):
        print(f"BEGIN {i}", flush=True)
        result = run_case(cases[i]["kind"], cases[i]["payload"], work)
        print(json.dumps({"i": i, **result}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 0)
