# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The newton-fluid extension itself: activation, argument validation, version guard, packaging, viewers."""

import inspect
import os
import subprocess
import sys
import tempfile
import types
import unittest
import zipfile
from pathlib import Path

import newton.viewer
import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton

FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
# the checkout (editable install), or None when the tests run from an installed wheel
CHECKOUT = Path(__file__).resolve().parents[2]
if not (CHECKOUT / "pyproject.toml").is_file():
    CHECKOUT = None


def run_python(code, env=None, timeout=600):
    full_env = dict(os.environ, **(env or {}))
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=full_env, timeout=timeout, check=False
    )


def fluid_model(device, count=8):
    builder = newton.ModelBuilder()
    for i in range(count):
        builder.add_particle(pos=wp.vec3(0.1 * i, 0.0, 1.0), vel=wp.vec3(0.0), mass=1.0, radius=0.05, flags=FLUID)
    return builder.finalize(device=device)


def test_fluid_flag(test, device):
    test.assertEqual(int(newton.ParticleFlags.FLUID), 1 << 2)
    test.assertIs(newton.ParticleFlags["FLUID"], newton.ParticleFlags.FLUID)
    test.assertIs(newton.ParticleFlags(4), newton.ParticleFlags.FLUID)
    test.assertIn("FLUID", [m.name for m in newton.ParticleFlags])
    # upstream members keep their values
    test.assertEqual(int(newton.ParticleFlags.ACTIVE), 1)


def test_solver_keywords(test, device):
    params = inspect.signature(newton.solvers.SolverXPBD).parameters
    for name in (
        "fluid_rest_distance",
        "fluid_smoothing_length",
        "fluid_rest_density",
        "fluid_cohesion",
        "fluid_viscosity",
        "fluid_vorticity",
        "fluid_relaxation",
        "fluid_density_ramp",
        "fluid_max_neighbors",
        "fluid_density_tolerance",
        "fluid_max_iterations",
        "fluid_warm_start",
        "max_diffuse_particles",
    ):
        test.assertIn(name, params)
        test.assertEqual(params[name].kind, inspect.Parameter.KEYWORD_ONLY)
    solver = newton.solvers.SolverXPBD(fluid_model(device), fluid_rest_distance=0.1, fluid_cohesion=0.3)
    test.assertAlmostEqual(solver.fluid_smoothing_length, 0.18)
    test.assertEqual(solver.fluid_cohesion, 0.3)
    with test.assertRaises(TypeError):
        newton.solvers.SolverXPBD(fluid_model(device), fluid_rest_distance=0.1, fluid_unknown=1.0)


BAD_ARGUMENTS = [
    ("fluid_rest_distance", 0.0),
    ("fluid_rest_distance", -0.1),
    ("fluid_rest_distance", float("nan")),
    ("fluid_rest_distance", "0.1"),
    ("fluid_smoothing_length", 0.05),
    ("fluid_smoothing_length", 0.5),
    ("fluid_rest_density", 0.0),
    ("fluid_rest_density", float("inf")),
    ("fluid_cohesion", -0.1),
    ("fluid_cohesion", 1.5),
    ("fluid_viscosity", -1.0),
    ("fluid_viscosity", 1.01),
    ("fluid_vorticity", -0.5),
    ("fluid_relaxation", 0.0),
    ("fluid_relaxation", 2.5),
    ("fluid_density_ramp", -0.001),
    ("fluid_density_ramp", 0.02),
    ("fluid_max_neighbors", -1),
    ("fluid_max_neighbors", 2.5),
    ("fluid_max_neighbors", True),
    ("max_diffuse_particles", -5),
    ("fluid_density_tolerance", -0.01),
    ("fluid_max_iterations", 0),
    ("fluid_max_iterations", -2),
    ("fluid_max_iterations", 65),
    ("fluid_warm_start", -0.1),
    ("fluid_warm_start", 0.6),
    ("fluid_warm_start", 1.0),
    ("fluid_compression_damping", -0.1),
    ("fluid_compression_damping", 0.5),
]


def test_bad_arguments_raise(test, device):
    model = fluid_model(device)
    for name, value in BAD_ARGUMENTS:
        kwargs = {"fluid_rest_distance": 0.1, name: value}
        with test.assertRaises(ValueError, msg=f"{name}={value!r}") as ctx:
            newton.solvers.SolverXPBD(model, **kwargs)
        test.assertIn(name, str(ctx.exception))
        test.assertIn(repr(value), str(ctx.exception))
        test.assertRegex(str(ctx.exception), r"[\[(].*,.*[\])]")  # names the valid range
        if name == "fluid_max_iterations":
            test.assertIn("[1, 64]", str(ctx.exception))
    with test.assertRaisesRegex(ValueError, "fluid_rest_distance=None"):
        newton.solvers.SolverXPBD(model)
    # the private tuning keyword (benchmarks, tests)
    from newton._src.solvers.xpbd.fluid.config import FluidTuning  # noqa: PLC0415

    with test.assertRaisesRegex(ValueError, r"scan_lanes=4 is invalid: expected an integer in \[0, 3\]"):
        FluidTuning(scan_lanes=4)
    with test.assertRaisesRegex(ValueError, "_fluid_tuning='fast' is invalid"):
        newton.solvers.SolverXPBD(model, fluid_rest_distance=0.1, _fluid_tuning="fast")
    solver = newton.solvers.SolverXPBD(model, fluid_rest_distance=0.1, _fluid_tuning=FluidTuning(scan_lanes=2))
    test.assertEqual(solver._fluid.search.lanes, 2)
    test.assertNotIn("_fluid_tuning", inspect.signature(newton.solvers.SolverXPBD).parameters)


def test_parameter_setters(test, device):
    solver = newton.solvers.SolverXPBD(fluid_model(device), fluid_rest_distance=0.1)
    solver.fluid_viscosity = 0.25
    test.assertEqual(solver.fluid_viscosity, 0.25)
    test.assertAlmostEqual(float(solver._fluid.params.numpy()[0]["viscosity"]), 0.25)
    with test.assertRaisesRegex(ValueError, "fluid_viscosity=3"):
        solver.fluid_viscosity = 3
    test.assertEqual(solver.fluid_viscosity, 0.25)
    solver.fluid_rest_density = 500.0
    test.assertAlmostEqual(float(solver._fluid.params.numpy()[0]["rest_density"]), 500.0)
    with test.assertRaises(AttributeError):
        solver.fluid_smoothing_length = 0.3
    # a model without fluid keeps the values but has nothing on the device
    plain = newton.solvers.SolverXPBD(newton.ModelBuilder().finalize(device=device))
    plain.fluid_cohesion = 0.5
    test.assertEqual(plain.fluid_cohesion, 0.5)
    test.assertIsNone(plain.fluid_density)


def test_version_guard(test, device):
    from newton._src.solvers.xpbd.fluid import upstream  # noqa: PLC0415

    solver_module = types.ModuleType("fake_solver_xpbd")

    class SolverXPBD:  # an upstream without the private names the extension patches
        __module__ = "fake_solver_xpbd"

        def step(self):
            pass

    sys.modules["fake_solver_xpbd"] = solver_module
    try:
        with test.assertRaises(RuntimeError) as ctx:
            upstream.check_names(types.SimpleNamespace(SolverXPBD=SolverXPBD))
        # names present, but a contact kernel of another launch signature
        SolverXPBD.__init__ = SolverXPBD.integrate_particles = SolverXPBD._apply_particle_deltas = lambda self: None
        SolverXPBD.reset = lambda self: None
        solver_module.solve_particle_particle_contacts = upstream.applied_particles
        with test.assertRaisesRegex(RuntimeError, "solve_particle_particle_contacts takes"):
            upstream.check_names(types.SimpleNamespace(SolverXPBD=SolverXPBD))
    finally:
        del sys.modules["fake_solver_xpbd"]
    message = str(ctx.exception)
    test.assertIn(f"found newton {newton.__version__}", message)
    test.assertIn("supports newton 1.8.0", message)
    test.assertIn("SolverXPBD._apply_particle_deltas", message)
    test.assertIn("solver_module.solve_particle_particle_contacts", message)
    # the installed upstream passes
    upstream.check_names(sys.modules["newton._src.solvers.xpbd"])


def test_upstream_behaviour_verified(test, device):
    from newton._src.solvers.xpbd.fluid import upstream  # noqa: PLC0415

    stock = dict(newton.solvers.SolverXPBD._fluid_stock)
    fluid = int(newton.ParticleFlags.FLUID)
    test.assertEqual(upstream.verify_behaviour(stock, device, fluid), [])

    def halved(self, model, state_in, state_out, particle_deltas, dt):  # another delta formula
        half = wp.empty_like(particle_deltas)
        wp.launch(_halve, dim=len(half), inputs=[particle_deltas], outputs=[half], device=particle_deltas.device)
        return stock["_apply_particle_deltas"](self, model, state_in, state_out, half, dt)

    failures = upstream.verify_behaviour({**stock, "_apply_particle_deltas": halved}, device, fluid)
    test.assertTrue(any("does not give x = x_pred + delta" in f for f in failures), failures)

    def inverted(self, model, state_in, state_out, particle_deltas, dt):  # the counter kept the other way round
        self._particle_delta_counter = 1 - self._particle_delta_counter
        out = stock["_apply_particle_deltas"](self, model, state_in, state_out, particle_deltas, dt)
        self._particle_delta_counter = 1 - self._particle_delta_counter
        return out

    failures = upstream.verify_behaviour({**stock, "_apply_particle_deltas": inverted}, device, fluid)
    test.assertTrue(any("buffer" in f or "predicted positions" in f for f in failures), failures)

    def broken(self, *args, **kwargs):  # an upstream whose step fails outright
        raise TypeError("step() got an unexpected keyword argument")

    failures = upstream.verify_behaviour({**stock, "step": broken}, device, fluid)
    test.assertEqual(len(failures), 1, failures)
    test.assertIn("the probe step raised TypeError", failures[0])


@wp.kernel
def _halve(x: wp.array[wp.vec3], y: wp.array[wp.vec3]):
    i = wp.tid()
    y[i] = 0.5 * x[i]


def test_refuses_to_activate_on_mismatch(test, device):
    # an upstream whose particle deltas are applied at half strength: the extension must refuse, and
    # SolverXPBD must then step as stock
    code = """
import inspect, numpy as np, warp as wp
import _newton_fluid_hook
def break_then_activate(xpbd):
    stock_apply = xpbd.SolverXPBD._apply_particle_deltas
    def halved(self, model, state_in, state_out, particle_deltas, dt):
        half = wp.array(0.5 * particle_deltas.numpy(), dtype=wp.vec3, device=particle_deltas.device)
        return stock_apply(self, model, state_in, state_out, half, dt)
    xpbd.SolverXPBD._apply_particle_deltas = halved
    import newton._src.solvers.xpbd.fluid  # activates
_newton_fluid_hook._ACTIVATORS["newton._src.solvers.xpbd"] = ("__main__", "break_then_activate")
import newton
from newton._src.solvers.xpbd import SolverXPBD
halved = SolverXPBD._fluid_stock["_apply_particle_deltas"]
print("active", "fluid_rest_distance" in inspect.signature(SolverXPBD).parameters)
b = newton.ModelBuilder()
for i in range(4):
    b.add_particle((0.1 * i, 0, 1), (0, 0, 0), 1.0, radius=0.05, flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID))
try:
    SolverXPBD(b.finalize(device="cpu"), fluid_rest_distance=0.1)
    print("refused False")
except RuntimeError as e:
    print("refused", "supports newton 1.8.0" in str(e) and f"found newton {newton.__version__}" in str(e))
    print("message", e)
print("stock", "fluid_rest_distance" not in inspect.signature(SolverXPBD).parameters, SolverXPBD._apply_particle_deltas is halved)
g = newton.ModelBuilder()
g.add_particle((0, 0, 1), (0, 0, 0), 1.0, radius=0.1)
g.add_particle((0.15, 0, 1), (0, 0, 0), 1.0, radius=0.1)
m = g.finalize(device="cpu")
s0, s1 = m.state(), m.state()
SolverXPBD(m).step(s0, s1, None, None, 1.0 / 60.0)
print("stepped", bool(np.all(np.isfinite(s1.particle_q.numpy()))))
"""
    out = run_python(code)
    lines = dict(line.split(" ", 1) for line in out.stdout.splitlines() if " " in line)
    test.assertEqual(lines.get("active"), "True", out.stdout + out.stderr)
    test.assertEqual(lines.get("refused"), "True", out.stdout + out.stderr)
    test.assertIn("_apply_particle_deltas", lines.get("message", ""))
    test.assertEqual(lines.get("stock"), "True True", out.stdout + out.stderr)
    test.assertEqual(lines.get("stepped"), "True", out.stdout + out.stderr)


def test_upstream_privates_named_only_in_the_seam(test, device):
    import re  # noqa: PLC0415

    from newton._src.solvers.xpbd.fluid import upstream  # noqa: PLC0415
    from newton._src.viewer.gl.fluid import upstream as viewer_upstream  # noqa: PLC0415

    root = Path(upstream.__file__).resolve().parents[4]  # the newton/ package holding the extension's files
    names = {e.name for e in upstream.SEAM if e.name not in ("__init__", "step", "reset")}
    viewer_names = [n for names in viewer_upstream.CLASS_NAMES.values() for n in names]
    viewer_names += [*viewer_upstream.RENDERER_NAMES, *viewer_upstream.FRAME_NAMES, *viewer_upstream.OTHER_PRIVATES]
    names |= {n for n in viewer_names if n.startswith("_")}
    pattern = re.compile(r"\b(" + "|".join(re.escape(n) for n in sorted(names)) + r")\b")
    seams = {Path(upstream.__file__).resolve(), Path(viewer_upstream.__file__).resolve()}
    files = [p for p in root.rglob("*.py") if "fluid" in p.name or "fluid" in p.parts]
    test.assertGreater(len(files), 20)
    found = []
    for path in files:
        if path.resolve() in seams or "tests" in path.parts:
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if pattern.search(line):
                found.append(f"{path.name}:{number}: {line.strip()}")
    test.assertEqual(found, [], "upstream privates named outside the two upstream.py modules")


def test_disable_environment_variable(test, device):
    code = "import newton, inspect; print(hasattr(newton.ParticleFlags, 'FLUID'), 'fluid_rest_distance' in inspect.signature(newton.solvers.SolverXPBD).parameters, hasattr(newton.viewer.ViewerNull, 'log_fluid'))"
    on = run_python(code)
    off = run_python(code, env={"NEWTON_FLUID_DISABLE": "1"})
    test.assertEqual(on.stdout.split()[-3:], ["True", "True", "True"], on.stderr)
    test.assertEqual(off.stdout.split()[-3:], ["False", "False", "False"], off.stderr)


def test_examples_listed(test, device):
    out = subprocess.run(
        [sys.executable, "-m", "newton.examples", "--list"], capture_output=True, text=True, timeout=600, check=False
    )
    test.assertEqual(out.returncode, 0, out.stderr)
    for name in (
        "dam_break",
        "foam",
        "multiworld",
        "interactive_tank",
        "multi_fluid_tank",
        "sdf_container",
        "wave_pool",
        "cup_transfer",
        "archimedes_screw",
    ):
        test.assertIn(f"fluid_xpbd_{name}", out.stdout)
    test.assertIn("basic_pendulum", out.stdout)  # upstream examples are still there
    described = subprocess.run(
        [sys.executable, "-m", "newton.examples", "--describe", "fluid_xpbd_dam_break"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    test.assertIn("Success criteria", described.stdout + described.stderr)


def test_test_runner_discovers_fluid_tests(test, device):
    out = subprocess.run(
        [sys.executable, "-m", "newton.tests", "-k", "test_fluid_flag_cpu", "--serial-fallback"],
        capture_output=True,
        text=True,
        timeout=1200,
        check=False,
        cwd=tempfile.gettempdir(),  # a checkout's docs/ folder would shadow upstream's docs package
    )
    log = out.stdout + out.stderr
    test.assertEqual(out.returncode, 0, log[-3000:])
    test.assertRegex(log, r"Ran 1 test")


def test_wheel_contents_and_clean_uninstall(test, device):
    if CHECKOUT is None:
        test.skipTest("needs the source checkout to build the wheel")
    with tempfile.TemporaryDirectory() as tmp:
        build = subprocess.run(
            [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", tmp, str(CHECKOUT)],
            capture_output=True,
            text=True,
            timeout=600,
            check=False,
        )
        test.assertEqual(build.returncode, 0, build.stderr[-3000:])
        wheel = next(Path(tmp).glob("newton_fluid-*.whl"))
        names = set(zipfile.ZipFile(wheel).namelist())
        test.assertIn("newton_fluid.pth", names)
        test.assertIn("_newton_fluid_hook.py", names)
        test.assertIn("newton/_src/solvers/xpbd/fluid/__init__.py", names)
        test.assertIn("newton/examples/fluid/example_fluid_xpbd_dam_break.py", names)
        for upstream in ("newton/__init__.py", "newton/_src/__init__.py", "newton/_src/solvers/xpbd/__init__.py"):
            test.assertNotIn(upstream, names)  # never shadow an upstream file
        # install into an empty environment and uninstall again: nothing may stay behind
        venv = Path(tmp) / "venv"
        subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=600)
        py = venv / "bin" / "python"
        site = Path(run_python_in(py, "import sysconfig; print(sysconfig.get_paths()['purelib'])"))
        before = {p.relative_to(site) for p in site.rglob("*")}
        pip = [sys.executable, "-m", "pip", "--python", str(py)]
        inst = subprocess.run([*pip, "install", "--no-deps", "--no-index", str(wheel)], capture_output=True, text=True)
        test.assertEqual(inst.returncode, 0, inst.stderr[-3000:])
        test.assertTrue((site / "newton" / "_src" / "solvers" / "xpbd" / "fluid" / "solver_fluid.py").is_file())
        test.assertTrue((site / "newton_fluid.pth").is_file())
        uninst = subprocess.run([*pip, "uninstall", "-y", "newton-fluid"], capture_output=True, text=True)
        test.assertEqual(uninst.returncode, 0, uninst.stderr[-3000:])
        after = {p.relative_to(site) for p in site.rglob("*") if "__pycache__" not in p.parts}
        test.assertEqual(after - before, set())


def run_python_in(python, code):
    return subprocess.run([str(python), "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_log_fluid_fallback(test, device):
    viewer = newton.viewer.ViewerNull(num_frames=1)
    positions = wp.array(np.zeros((4, 3), dtype=np.float32), dtype=wp.vec3, device=device)
    radii = wp.full(4, 0.05, dtype=float, device=device)
    viewer.begin_frame(0.0)
    viewer.log_fluid("/fluid", positions, radii=radii, color=(0.1, 0.2, 0.8, 0.9), absorption=(1.0, 0.5, 0.2), ior=1.33)
    viewer.log_fluid("/fluid2", positions, radii=0.05, radius_scale=2.0)
    viewer.log_fluid("/fluid", None)
    viewer.end_frame()
    with test.assertRaisesRegex(ValueError, "radius_scale=0"):
        viewer.log_fluid("/fluid", positions, radii=0.05, radius_scale=0)


def _free_port():
    import socket  # noqa: PLC0415

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_log_fluid_every_viewer(test, device):
    """Every non-GL viewer takes every log_fluid call: USD as a surface mesh in the batch colour, the rest too."""
    import tempfile  # noqa: PLC0415

    builder = newton.ModelBuilder()
    builder.add_particle_grid(
        pos=wp.vec3(0.0),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=3,
        dim_y=3,
        dim_z=3,
        cell_x=0.1,
        cell_y=0.1,
        cell_z=0.1,
        mass=1.0,
        jitter=0.0,
        radius_mean=0.05,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    model = builder.finalize(device=device)
    state = model.state()
    axes = [
        wp.array(np.tile(v, (27, 1)).astype(np.float32), dtype=wp.vec4, device=device)
        for v in np.eye(4)[:3] + [0, 0, 0, 1]
    ]
    color = (0.9, 0.3, 0.1, 0.5)
    with tempfile.TemporaryDirectory() as tmp:
        viewers = {
            "null": lambda: newton.viewer.ViewerNull(num_frames=3),
            "file": lambda: newton.viewer.ViewerFile(os.path.join(tmp, "rec.json")),
            "usd": lambda: newton.viewer.ViewerUSD(os.path.join(tmp, "fluid.usda"), num_frames=3),
            "rerun": lambda: newton.viewer.ViewerRerun(web_port=_free_port(), grpc_port=_free_port()),
            "viser": lambda: newton.viewer.ViewerViser(host="127.0.0.1", port=_free_port(), verbose=False),
        }
        for kind, make in viewers.items():
            with test.subTest(viewer=kind):
                viewer = make()
                viewer.set_model(model)
                for frame, count in enumerate((27, 8, 27)):
                    viewer.begin_frame(frame / 60.0)
                    viewer.log_state(state)
                    viewer.log_fluid(
                        "/fluid",
                        state.particle_q[:count],
                        radii=model.particle_radius[:count],
                        radius_scale=1.5,
                        color=color,
                        absorption=(1.0, 2.0, 3.0),
                        ior=1.4,
                        reflectance=0.05,
                        specular_intensity=0.3,
                        specular_power=64.0,
                        blur_radius_world=0.02,
                        anisotropy=axes[0][:count],
                        anisotropy_secondary=axes[1][:count],
                        anisotropy_tertiary=axes[2][:count],
                    )
                    viewer.log_fluid("/other", state.particle_q, radii=0.05, hidden=frame == 1)
                    if frame == 2:
                        viewer.log_fluid("/other", None)
                    viewer.end_frame()
                viewer.close()
        from pxr import Usd, UsdGeom, UsdShade  # noqa: PLC0415

        stage = Usd.Stage.Open(os.path.join(tmp, "fluid.usda"))
        prims = [p for p in stage.Traverse() if p.GetName() == "fluid"]
        test.assertEqual(len(prims), 1, [str(p.GetPath()) for p in stage.Traverse()])
        test.assertTrue(prims[0].IsA(UsdGeom.Mesh))
        material, _ = UsdShade.MaterialBindingAPI(prims[0]).ComputeBoundMaterial()
        shader = material.ComputeSurfaceSource()[0]
        np.testing.assert_allclose(shader.GetInput("diffuseColor").Get(), color[:3], atol=1.0e-6)
        test.assertAlmostEqual(shader.GetInput("ior").Get(), 1.4, places=5)


def test_log_fluid_draws_points_with_batch_color(test, device):
    calls = []

    class Recorder(newton.viewer.ViewerNull):
        def log_points(self, name, points, radii=None, colors=None, hidden=False):
            calls.append((name, points, radii, colors, hidden))

    viewer = Recorder(num_frames=1)
    positions = wp.array(np.ones((3, 3), dtype=np.float32), dtype=wp.vec3, device=device)
    radii = wp.full(3, 0.05, dtype=float, device=device)
    viewer.log_fluid("/water", positions, radii=radii, radius_scale=2.0, color=(0.1, 0.2, 0.8, 0.5))
    name, points, r, colors, hidden = calls[-1]
    test.assertEqual(name, "/water")
    test.assertIs(points, positions)
    np.testing.assert_allclose(r.numpy(), 0.1, rtol=1.0e-6)
    np.testing.assert_allclose(colors.numpy(), [(0.1, 0.2, 0.8)] * 3, rtol=1.0e-6)
    test.assertFalse(hidden)


class TestFluidExtension(unittest.TestCase):
    pass


cpu = [wp.get_device("cpu")]
devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        # host-side checks run once; device code runs on every device
        per_device = _name in (
            "test_solver_keywords",
            "test_bad_arguments_raise",
            "test_parameter_setters",
            "test_log_fluid_fallback",
            "test_upstream_behaviour_verified",
        )
        # the web viewers print their addresses
        check_output = _name != "test_log_fluid_every_viewer"
        add_function_test(
            TestFluidExtension, _name, _func, devices=devices if per_device else cpu, check_output=check_output
        )

if __name__ == "__main__":
    unittest.main(verbosity=2)
