"""Mass properties from geometry against MuJoCo 4.0: for meshes in every
format nudyn reads (binary STL, OBJ with quads, MSH) and every `inertia`
mode (legacy, convex, exact, shell), with `scale`, `refpos` and `refquat`,
for several geoms combined per body, `shellinertia` primitives and
`fullinertia`, `nudyn describe --json` must give MuJoCo's body_mass,
body_inertia, body_ipos and body_iquat to 1e-9 (relative to each vector's
size). What MuJoCo refuses, nudyn refuses too.

The meshes are tests/fixtures/meshes/ (see its README.md): a cube, a
tetrahedron, a non-convex L-shaped prism (where legacy, convex and exact
differ) and an open box (a shell without its lid)."""

from __future__ import annotations

import json
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, IMPORTER_FIXTURES, ROOT

MESHES = ROOT / "tests" / "fixtures" / "meshes"
SHAPES = ["cube", "tetrahedron", "l_shape", "open_box"]
FORMATS = ["stl", "obj", "msh"]
MODES = ["legacy", "convex", "exact", "shell"]
SENSOR_FIXTURES = sorted((ROOT / "tests" / "fixtures" / "sensors").glob("*.xml"))
TOLERANCE = 1e-9


def describe(nudyn, path):
    proc = subprocess.run([str(nudyn), "describe", str(path), "--json"], capture_output=True, text=True)
    return proc


def assert_bodies_match(described, m, label):
    bodies = described["bodies"]
    assert len(bodies) == m.nbody - 1, label
    for b, body in enumerate(bodies, start=1):
        if body["mass_unknown"]:  # a height field's mass, which nudyn leaves out
            continue
        for field, ours, theirs in [
            ("body_mass", [body["mass"]], [m.body_mass[b]]),
            ("body_inertia", body["inertia"], m.body_inertia[b]),
            ("body_ipos", body["ipos"], m.body_ipos[b]),
            ("body_iquat", body["iquat"], m.body_iquat[b]),
        ]:
            ours, theirs = np.asarray(ours, float), np.asarray(theirs, float)
            scale = max(np.max(np.abs(theirs)), 1e-300)
            err = np.max(np.abs(ours - theirs)) / scale
            assert err <= TOLERANCE, f"{label}, body {body['name']}: {field} {ours} vs MuJoCo {theirs} ({err:.1e})"


def compare(nudyn, path, label=None):
    label = label or path.name
    m = mujoco.MjModel.from_xml_path(str(path))
    proc = describe(nudyn, path)
    assert proc.returncode == 0, f"{label}: nudyn refused what MuJoCo compiles:\n{proc.stderr}"
    assert_bodies_match(json.loads(proc.stdout), m, label)


def both_refuse(nudyn, path, mujoco_says, nudyn_says):
    with pytest.raises(ValueError, match=mujoco_says):
        mujoco.MjModel.from_xml_path(str(path))
    proc = describe(nudyn, path)
    assert proc.returncode != 0, f"{path.name}: nudyn accepted what MuJoCo refuses"
    assert nudyn_says in proc.stderr, proc.stderr


def mesh_scene(tmp_path, mesh_attributes, geoms='<geom type="mesh" mesh="m" pos="0.05 -0.1 0.2" euler="0 30 60" density="800"/>'):
    xml = f"""<mujoco model="mesh_scene">
  <asset><mesh name="m" {mesh_attributes}/></asset>
  <worldbody>
    <body name="probe" pos="0.1 0.2 0.3" euler="10 20 30">
      <freejoint/>
      {geoms}
    </body>
  </worldbody>
</mujoco>"""
    path = tmp_path / "scene.xml"
    path.write_text(xml)
    return path


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("shape", SHAPES)
def test_each_shape_format_and_mode(nudyn, tmp_path, shape, fmt, mode):
    path = mesh_scene(tmp_path, f'file="{MESHES / f"{shape}.{fmt}"}" inertia="{mode}"')
    compare(nudyn, path, f"{shape}.{fmt} inertia={mode}")


POLYGON_SHAPES = ["hex_prism", "l_ngon", "l_ngon_offset", "collinear_prism", "warped_pentagon"]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("shape", POLYGON_SHAPES)
def test_obj_polygons_of_more_than_four_corners(nudyn, tmp_path, shape, mode):
    """Prisms whose caps are polygons of 5 to 8 corners, cut as MuJoCo's
    tinyobjloader cuts them: a fan over the L's reflex corner (covering
    part of it twice, which legacy's and shell's unsigned sums count
    twice), and with the L away from the origin only part of the cap. What
    MuJoCo refuses in a mode, nudyn must refuse too."""
    path = mesh_scene(tmp_path, f'file="{MESHES / f"{shape}.obj"}" inertia="{mode}"')
    label = f"{shape}.obj inertia={mode}"
    try:
        mujoco.MjModel.from_xml_path(str(path))
    except ValueError as refusal:
        proc = describe(nudyn, path)
        assert proc.returncode != 0, f"{label}: nudyn accepted what MuJoCo refuses ({refusal})"
        return
    compare(nudyn, path, label)


FITTED_KINDS = ["sphere", "capsule", "cylinder", "ellipsoid", "box"]


@pytest.mark.parametrize("fitaabb", ["false", "true"])
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("shape", ["l_shape.stl", "tetrahedron.obj", "cube.msh", "l_ngon_offset.obj"])
def test_primitives_fitted_to_meshes(nudyn, tmp_path, shape, mode, fitaabb):
    """A primitive geom with a mesh takes its size from the mesh's inertia
    box (or, with <compiler fitaabb>, its bounding box in the mesh frame,
    and its centre), times fitscale, and the mesh frame: each kind alone
    beside a box, plain, scaled and with a shell, with its own size and a
    mass. The body's mass properties follow from the fitted size, position
    and orientation; a capsule the box leaves no length is refused by both."""
    for kind in FITTED_KINDS:
        for extra in ["", 'fitscale="1.3" shellinertia="true"', 'size="0.2 0.3 0.4" mass="2"']:
            geoms = (f'<geom type="{kind}" mesh="m" pos="0.05 -0.1 0.2" euler="0 30 60" {extra}/>'
                     '<geom type="box" size="0.1 0.2 0.05" pos="0.2 0.2 -0.1" euler="15 0 45"/>')
            path = mesh_scene(tmp_path, f'file="{MESHES / shape}" inertia="{mode}"', geoms)
            path.write_text(path.read_text().replace("<mujoco model=\"mesh_scene\">",
                                                     f'<mujoco model="mesh_scene"><compiler fitaabb="{fitaabb}"/>'))
            label = f"{kind} fitted to {shape} inertia={mode} fitaabb={fitaabb} {extra}"
            try:
                mujoco.MjModel.from_xml_path(str(path))
            except ValueError as refusal:
                proc = describe(nudyn, path)
                assert proc.returncode != 0, f"{label}: nudyn accepted what MuJoCo refuses ({refusal})"
                assert "must be positive" in proc.stderr, proc.stderr
                continue
            compare(nudyn, path, label)


def test_the_modes_differ_where_they_should(nudyn, tmp_path):
    """On the L-shape legacy, convex and exact give three different masses
    (so the cases above tell the modes apart); on the cube they agree."""
    masses = {}
    for shape in ["l_shape", "cube"]:
        for mode in ["legacy", "convex", "exact"]:
            path = mesh_scene(tmp_path, f'file="{MESHES / f"{shape}.stl"}" inertia="{mode}"')
            masses[shape, mode] = json.loads(describe(nudyn, path).stdout)["bodies"][0]["mass"]
    l_shape = [masses["l_shape", mode] for mode in ["legacy", "convex", "exact"]]
    assert len(set(l_shape)) == 3, l_shape
    cube = [masses["cube", mode] for mode in ["legacy", "convex", "exact"]]
    assert np.ptp(cube) <= 1e-12 * cube[0], cube


@pytest.mark.parametrize(
    "attributes",
    [
        'scale="2 0.5 1.5"',
        'refpos="0.1 -0.2 0.05" refquat="0.9 0.1 0.3 0.2"',
        'scale="0.5 1.25 0.75" refpos="0.3 0 0" refquat="0 0 0 1" inertia="exact"',
        'scale="-1 1 1"',
        'scale="1 -0.5 1" inertia="shell"',
    ],
)
@pytest.mark.parametrize("shape", ["tetrahedron", "l_shape"])
def test_scale_refpos_refquat(nudyn, tmp_path, shape, attributes):
    for fmt in FORMATS:
        path = mesh_scene(tmp_path, f'file="{MESHES / f"{shape}.{fmt}"}" {attributes}')
        compare(nudyn, path, f"{shape}.{fmt} {attributes}")


@pytest.mark.parametrize("mode", MODES)
def test_mirrored_meshes(nudyn, tmp_path, mode):
    for shape in ["l_shape", "tetrahedron"]:
        for fmt in FORMATS:
            path = mesh_scene(tmp_path, f'file="{MESHES / f"{shape}.{fmt}"}" scale="1 -1.5 1" inertia="{mode}"')
            compare(nudyn, path, f"{shape}.{fmt} mirrored {mode}")


def test_several_geoms_per_body_with_density_and_mass(nudyn, tmp_path):
    geoms = f"""<geom type="mesh" mesh="m" pos="0.05 -0.1 0.2" euler="0 30 60" density="800"/>
      <geom type="mesh" mesh="t" pos="-0.3 0.1 0" quat="0.2 0.4 -0.1 0.8" mass="3.5"/>
      <geom type="box" size="0.1 0.2 0.05" pos="0.2 0.2 -0.1" euler="15 0 45"/>
      <geom type="capsule" fromto="0 0 0 0.3 0.1 0.4" size="0.03" shellinertia="true" density="50"/>"""
    mesh = f'file="{MESHES / "l_shape.obj"}" inertia="exact"/><mesh name="t" file="{MESHES / "tetrahedron.msh"}" inertia="convex"'
    compare(nudyn, mesh_scene(tmp_path, mesh, geoms))


@pytest.mark.parametrize("kind", ["sphere", "capsule", "cylinder", "ellipsoid", "box"])
def test_shellinertia_of_primitives(nudyn, tmp_path, kind):
    size = {"sphere": "0.3", "capsule": "0.1 0.4", "cylinder": "0.2 0.3", "ellipsoid": "0.1 0.2 0.3", "box": "0.1 0.2 0.3"}[kind]
    geoms = f'<geom type="{kind}" size="{size}" shellinertia="true" euler="10 20 30" pos="0.1 0 0"/><geom type="sphere" size="0.05" pos="0 0.3 0"/>'
    compare(nudyn, mesh_scene(tmp_path, f'file="{MESHES / "cube.stl"}"', geoms), f"shell {kind}")


def test_fullinertia_principal_axes(nudyn, tmp_path):
    for full in ["2 3 4 0.1 -0.2 0.3", "1 1 1 0 0 0", "3 2 1 0 0 0", "1 2 2 0 0 0.5", "5 5 2 1 0 0"]:
        inertial = f'<inertial pos="0.1 0 0" mass="2" fullinertia="{full}"/>'
        compare(nudyn, mesh_scene(tmp_path, f'file="{MESHES / "cube.stl"}"', inertial), f"fullinertia {full}")


def test_random_full_tensors(nudyn, tmp_path):
    """Seeded random full tensors scaled from 1e-6 to 1e6, one in three
    with two moments 1e-9 apart (where the axes in their plane are the
    eigen-solver's choice): body_iquat must be MuJoCo's to 1e-9 in every
    case, which a solver stopping by another rule misses."""
    rng = np.random.default_rng(3)
    bodies = []
    for k in range(60):
        second = rng.uniform(0.05, 1, 3)
        if k % 3 == 0:
            second[1] = second[0] * (1 + 1e-9)
        moments = np.array([second[1] + second[2], second[0] + second[2], second[0] + second[1]])
        axes, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        t = axes @ np.diag(moments * 10 ** rng.uniform(-6, 6)) @ axes.T
        full = " ".join(repr(float(x)) for x in [t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]])
        bodies.append(f'<body name="b{k}" pos="{k} 0 0"><freejoint/><inertial pos="0 0 0" mass="1" fullinertia="{full}"/></body>')
    path = tmp_path / "full_tensors.xml"
    path.write_text(f"<mujoco><worldbody>{''.join(bodies)}</worldbody></mujoco>")
    compare(nudyn, path, "random full tensors")


def test_ascii_stl_is_refused_like_mujoco(nudyn, tmp_path):
    path = mesh_scene(tmp_path, f'file="{MESHES / "cube_ascii.stl"}"')
    both_refuse(nudyn, path, "ASCII", "ASCII")


def test_misoriented_faces_in_exact_mode_are_refused_like_mujoco(nudyn, tmp_path):
    # The tetrahedron with its last face reversed.
    mesh = 'vertex="0 0 0 1 0 0 0 1 0 0 0 1" face="0 2 1 0 1 3 0 3 2 1 3 2" inertia="exact"'
    both_refuse(nudyn, mesh_scene(tmp_path, mesh), "inconsistent orientation", "inconsistent orientation")


def test_flat_mesh_of_a_colliding_geom_is_refused_like_mujoco(nudyn, tmp_path):
    mesh = 'vertex="0 0 0 1 0 0 0 1 0 1 1 0" face="0 1 2 1 3 2" inertia="shell"'
    both_refuse(nudyn, mesh_scene(tmp_path, mesh), "coplanar", "coplanar")
    # Without collisions MuJoCo builds no hull, and the shell has its mass.
    geoms = '<geom type="mesh" mesh="m" contype="0" conaffinity="0"/>'
    compare(nudyn, mesh_scene(tmp_path, mesh, geoms))


def test_vertices_without_faces_take_the_hull(nudyn, tmp_path):
    for mode in MODES:
        mesh = f'vertex="0 0 0 1 0 0 0 1.5 0 0 0 2 0.2 0.2 0.2 1 0.75 0.5" inertia="{mode}"'
        compare(nudyn, mesh_scene(tmp_path, mesh), f"vertex-only {mode}")


def test_maxhullvert_below_the_hull_is_refused(nudyn, tmp_path):
    path = mesh_scene(tmp_path, f'file="{MESHES / "l_shape.stl"}" inertia="convex" maxhullvert="5"')
    mujoco.MjModel.from_xml_path(str(path))  # MuJoCo simplifies the hull with qhull
    proc = describe(nudyn, path)
    assert proc.returncode != 0 and "maxhullvert" in proc.stderr, proc.stderr
    # A limit the hull respects changes nothing.
    compare(nudyn, mesh_scene(tmp_path, f'file="{MESHES / "l_shape.stl"}" inertia="convex" maxhullvert="12"'))


def test_mesh_defaults_and_meshdir(nudyn, tmp_path):
    (tmp_path / "parts").mkdir()
    for fmt in FORMATS:
        (tmp_path / "parts" / f"l.{fmt}").write_bytes((MESHES / f"l_shape.{fmt}").read_bytes())
    xml = """<mujoco>
  <compiler meshdir="parts"/>
  <default><mesh scale="1 2 1" inertia="exact"/><default class="thin"><mesh inertia="shell"/></default></default>
  <asset><mesh file="l.stl"/><mesh name="thin" class="thin" file="l.obj"/><mesh name="plain" file="l.msh" inertia="legacy"/></asset>
  <worldbody>
    <body name="a"><joint/><geom type="mesh" mesh="l"/></body>
    <body name="b"><joint/><geom type="mesh" mesh="thin"/></body>
    <body name="c"><joint/><geom type="mesh" mesh="plain"/></body>
  </worldbody>
</mujoco>"""
    path = tmp_path / "defaults.xml"
    path.write_text(xml)
    compare(nudyn, path)


@pytest.mark.parametrize("fmt", FORMATS)
def test_content_type_and_upper_case_extensions(nudyn, tmp_path, fmt):
    """A mesh file with an upper-case extension and each content_type, read
    as MuJoCo 4.0 reads it: model/vnd.mujoco.msh reads MSH whatever the
    extension, another well-formed type leaves it to the extension and
    finds nothing for an .msh file, a malformed type is no type. Where
    MuJoCo refuses, nudyn refuses too."""
    upper = tmp_path / f"L_{fmt}.{fmt.upper()}"
    upper.write_bytes((MESHES / f"l_shape.{fmt}").read_bytes())
    for content_type in ["model/stl", "model/obj", "model/vnd.mujoco.msh", "model/ply", "model/x;a=b", "foo"]:
        path = mesh_scene(tmp_path, f'file="{upper}" content_type="{content_type}" inertia="exact"')
        label = f"{upper.name} as {content_type}"
        try:
            # A fresh process: MuJoCo caches a mesh by its file name, whatever its content_type.
            subprocess.run([sys.executable, "-c", f"import mujoco; mujoco.MjModel.from_xml_path({str(path)!r})"],
                           check=True, capture_output=True)
        except subprocess.CalledProcessError:
            proc = describe(nudyn, path)
            assert proc.returncode != 0, f"{label}: nudyn accepted what MuJoCo refuses"
            continue
        compare(nudyn, path, label)


@pytest.mark.parametrize("corners", [100, 101, 215])
def test_polygons_of_more_than_100_corners_leave_no_triangles(nudyn, tmp_path, corners):
    """MuJoCo 4.0 cuts an OBJ polygon of up to 100 corners and keeps nothing
    of a larger one (Menagerie's stretch_3 gripper has one of 215): a
    pyramid on such a base is its sides alone, in every mode."""
    rng = np.random.default_rng(corners)
    angles = np.sort(rng.uniform(0, 2 * np.pi, corners))
    radii = 0.1 * (1 + 0.3 * rng.uniform(size=corners))
    # An elongated base: principal axes well apart, so that they are well defined.
    lines = [f"v {r * np.cos(a) + 0.3:.9g} {0.5 * r * np.sin(a) + 0.2:.9g} 0.05" for a, r in zip(angles, radii)]
    lines += ["v 0.3 0.2 -0.05", "f " + " ".join(str(k + 1) for k in range(corners))]
    lines += [f"f {(k + 1) % corners + 1} {k + 1} {corners + 1}" for k in range(corners)]
    (tmp_path / "pyramid.obj").write_text("\n".join(lines) + "\n")
    for mode in ["legacy", "exact", "shell"]:
        path = mesh_scene(tmp_path, f'file="{tmp_path / "pyramid.obj"}" inertia="{mode}"')
        model = mujoco.MjModel.from_xml_path(str(path))
        assert (model.mesh_facenum[0] > corners) == (corners <= 100)
        compare(nudyn, path, f"{corners}-corner base, {mode}")


@pytest.mark.parametrize("path", EXAMPLES + IMPORTER_FIXTURES + SENSOR_FIXTURES, ids=lambda p: p.stem)
def test_every_fixture_and_example(nudyn, path):
    proc = describe(nudyn, path)
    if proc.returncode != 0:
        pytest.skip(f"nudyn does not import {path.name}: {proc.stderr.strip()}")
    assert_bodies_match(json.loads(proc.stdout), mujoco.MjModel.from_xml_path(str(path)), path.name)


def test_random_tetrahedra(nudyn, tmp_path):
    """Seeded random tetrahedra of sizes from 1 cm to 10 m, in the four
    modes. Mass, moments and centre must be MuJoCo's to 1e-9. The mesh frame
    comes from MuJoCo 4.0's early-stopping eigen-decomposition, whose stop
    nudyn reproduces by a fitted rule (src/mjcf/inertia.rs): body_iquat must
    agree to 1e-9 in all but a few cases, and to 1e-6 in all."""
    import struct

    rng = np.random.default_rng(7)
    quat_misses = []
    for k in range(100):
        vertices = rng.normal(size=(4, 3)).astype(np.float32) * np.float32(10 ** rng.uniform(-2, 1))
        a, b, c, d = vertices.astype(float)
        outward = np.dot(np.cross(b - a, c - a), d - a) <= 0
        faces = [(0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)] if outward else [(0, 2, 1), (0, 1, 3), (1, 2, 3), (2, 0, 3)]
        # A new file name each time: MuJoCo caches meshes by file name.
        stl = tmp_path / f"tetrahedron{k}.stl"
        body = b"".join(
            struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *vertices[i]) for i in f) + b"\0\0" for f in faces
        )
        stl.write_bytes(b" " * 80 + struct.pack("<i", len(faces)) + body)
        mode = MODES[k % 4]
        path = mesh_scene(tmp_path, f'file="{stl}" inertia="{mode}"')
        m = mujoco.MjModel.from_xml_path(str(path))
        proc = describe(nudyn, path)
        assert proc.returncode == 0, proc.stderr
        ours = json.loads(proc.stdout)["bodies"][0]
        for field, theirs in [("mass", [m.body_mass[1]]), ("inertia", m.body_inertia[1]), ("ipos", m.body_ipos[1])]:
            got = np.atleast_1d(ours[field])
            assert np.max(np.abs(got - theirs)) <= TOLERANCE * np.max(np.abs(theirs)), (k, mode, field, got, theirs)
        quat_error = np.max(np.abs(np.asarray(ours["iquat"]) - m.body_iquat[1]))
        assert quat_error <= 1e-6, (k, mode, ours["iquat"], m.body_iquat[1])
        if quat_error > TOLERANCE:
            quat_misses.append((k, mode, quat_error))
    assert len(quat_misses) <= 3, quat_misses
