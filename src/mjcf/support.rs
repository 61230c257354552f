//! The table of MJCF support in docs/mjcf-support.md, rendered from the
//! importer's own lists (the attributes each element accepts, the
//! sections and default children it ignores, the elements it refuses and
//! why), so that the table says what the importer does.
//! `tests/all/mjcf_support.rs` fails when the file differs from it.

use std::fmt::Write;

use super::{actuator, attributes, bodies, defaults, equality, keyframe, mesh, reader, sensor, tendon};
use crate::vehicle::SensorKind;

/// docs/mjcf-support.md: element and attribute, read or ignored with a
/// warning or refused with the importer's reason.
pub fn support_table() -> String {
    let mut out = format!(
        "# MJCF support\n\n\
         Generated from the importer's own lists (`src/mjcf/support.rs`; \
         `NUDYN_WRITE_DOCS=1 cargo test --release -p nudyn --test mjcf_support` rewrites it, \
         and the test fails while this file differs). What nudyn does with each element of a \
         MuJoCo 4.0 model file:\n\n\
         - **read**: the element and the attributes listed are accepted; an attribute or element \
         not listed anywhere here is refused as unknown, naming the element and line. The lists do \
         not tell an attribute nudyn models from one it accepts because it has no effect on what \
         nudyn computes (contact, rendering and solver settings): [cli.md](cli.md) says what is \
         modelled. The refusals of particular values (a nonzero `wind`, \
         a `gaintype` other than fixed and affine, …) are in the importer's messages. \
         `noslip_iterations`, `noslip_tolerance` and `<flag island>` are modelled: MuJoCo's no-slip \
         pass over the friction-loss rows runs as MuJoCo 4.0 runs it. Mesh files (`<mesh file>`): binary STL, MSH and OBJ, whose \
         triangles are read as written, quads split along their shorter diagonal and polygons of five \
         corners or more cut by tinyobjloader's ear clipping as MuJoCo 4.0's reader cuts them (a \
         polygon that refers to a vertex defined after it is refused). A sphere, capsule, cylinder, \
         ellipsoid or box `<geom>` with a `mesh` is fitted to the mesh as MuJoCo's compiler fits it \
         (its inertia box, or its bounding box with `<compiler fitaabb=\"true\">`, times `fitscale`), \
         and takes that primitive's mass. A mesh file is read only for a geom whose mass nudyn \
         computes (in a body that takes its mass from its geoms, in `inertiagrouprange`): a mesh that \
         only world geoms, or geoms whose mass does not count, use is never opened (and MuJoCo's check \
         of a colliding mesh geom's convex hull is made only for the meshes read). Backslashes in file \
         names (`<mesh file>`, `meshdir`, `assetdir`, `<include file>`) are separators, as MuJoCo reads \
         them on every system; a file named must be a regular file (a named pipe is refused, not \
         waited on). nudyn models no contacts: each pair of geoms MuJoCo would collide at the \
         initial pose gets a warning (contype and conaffinity sharing a bit, not the same or welded \
         bodies, not parent and child unless `<flag filterparent>` is disabled, not excluded, and \
         closer than the larger margin; computed for spheres, capsules and planes, other shapes are \
         not checked). The `<replicate>`s of a file may produce at most {} \
         elements (each replicate's copies times the elements inside it, summed).\n\
         - **ignored with a warning**: no effect on the dynamics; each occurrence gives one warning.\n\
         - **refused**: the import stops with the reason below.\n",
        reader::MAX_REPLICATED_ELEMENTS
    );

    out.push_str("\n## Sections ignored with a warning\n\n");
    out.push_str("| section | |\n|---|---|\n");
    for section in reader::IGNORED_SECTIONS {
        let _ = writeln!(out, "| `<{section}>` | ignored with a warning |");
    }
    out.push_str(
        "\n`<keyframe>`: each `<key>` is checked as MuJoCo checks it (every vector it gives has the model's size) \
         and kept; `nudyn linearize --keyframe` starts from it.\n",
    );
    out.push_str(
        "\n`<custom>`: a `<text name=\"nudyn:modal:BODY\" data=\"FILE\"/>` names the modal data file that makes \
         BODY flexible ([flexible.md](flexible.md)); anything else in the section is ignored with a warning.\n",
    );
    out.push_str("\nIn `<default>`, these children are ignored with a warning: ");
    out.push_str(&code_list(defaults::IGNORED_DEFAULTS, true));
    out.push_str(". In bodies and in the world body: ");
    out.push_str(&code_list(reader::IGNORED_IN_BODIES, true));
    out.push_str(
        "; in the world body, `<geom>` too (it belongs to no moving body), unless a spatial tendon wraps around \
         it: then it is used, and only its contacts are left out (no warning when it has none).\n",
    );

    write_elements_read(&mut out);

    out.push_str("\n## Refused\n\n| element or attribute | reason |\n|---|---|\n");
    for (tag, reason) in reader::UNSUPPORTED_CHILDREN {
        let _ = writeln!(out, "| `<{tag}>` | {reason} |");
    }
    for (tag, reason) in actuator::REFUSED_ACTUATORS {
        let _ = writeln!(out, "| `<actuator>/<{tag}>` | {reason} |");
    }
    for (attribute, reason) in actuator::REFUSED_TRANSMISSIONS {
        let _ = writeln!(out, "| actuator `{attribute}=` | {reason} |");
    }
    for (tags, reason) in sensor::REFUSED_SENSORS {
        for tag in *tags {
            let _ = writeln!(out, "| `<sensor>/<{tag}>` | {reason} |");
        }
    }
    for tag in equality::REFUSED_EQUALITIES {
        let _ = writeln!(out, "| `<equality>/<{tag}>` | an equality constraint on a flex (nudyn models no flexes) |");
    }
    out
}

/// The rows of "Elements read, and their attributes".
fn write_elements_read(out: &mut String) {
    out.push_str("\n## Elements read, and their attributes\n\n");
    out.push_str("| element | attributes |\n|---|---|\n");
    let joint = attributes::names(defaults::JOINT_ATTRIBUTES);
    let geom = attributes::names(defaults::GEOM_ATTRIBUTES);
    let site = attributes::names(defaults::SITE_ATTRIBUTES);
    let mesh_attributes = attributes::names(mesh::MESH_ATTRIBUTES);
    let compiler = attributes::names(reader::COMPILER_ATTRIBUTES);
    let option = attributes::names(reader::OPTION_ATTRIBUTES);
    let flag = attributes::names(reader::FLAG_ATTRIBUTES);
    let body = attributes::names(bodies::BODY_ATTRIBUTES);
    let frame = attributes::names(bodies::FRAME_ATTRIBUTES);
    let replicate = attributes::names(bodies::REPLICATE_ATTRIBUTES);
    let inertial = attributes::names(bodies::INERTIAL_ATTRIBUTES);
    let freejoint = attributes::names(bodies::FREEJOINT_ATTRIBUTES);
    let key = attributes::names(keyframe::KEY_ATTRIBUTES);
    let elements: [(&str, &[&str]); 13] = [
        ("compiler", &compiler),
        ("option", &option),
        ("option/flag", &flag),
        ("body", &body),
        ("frame", &frame),
        ("replicate", &replicate),
        ("inertial", &inertial),
        ("joint", &joint),
        ("freejoint", &freejoint),
        ("geom", &geom),
        ("site", &site),
        ("asset/mesh", &mesh_attributes),
        ("keyframe/key", &key),
    ];
    for (element, attributes) in elements {
        let _ = writeln!(out, "| `<{element}>` | {} |", code_list(attributes, false));
    }
    for (element, attributes) in
        [("fixed", tendon::tendon_attributes(false)), ("spatial", tendon::tendon_attributes(true))]
    {
        let _ = writeln!(out, "| `<tendon>/<{element}>` | {} |", code_list(&attributes, false));
    }
    for (path, table) in tendon::PATH_ELEMENTS {
        let (parent, child) = path.split_once('/').expect("parent/child");
        let _ = writeln!(out, "| `<{parent}>/<{child}>` | {} |", code_list(&attributes::names(table), false));
    }
    for (tag, kind) in actuator::ACTUATOR_KINDS {
        let _ = writeln!(out, "| `<actuator>/<{tag}>` | {} |", code_list(&actuator::attributes(*kind, false), false));
    }
    for kind in SensorKind::ALL {
        let _ = writeln!(out, "| `<sensor>/<{}>` | {} |", kind.name(), code_list(&sensor::attributes(kind), false));
    }
    for (tag, own) in equality::EQUALITY_ATTRIBUTES {
        let _ = writeln!(out, "| `<equality>/<{tag}>` | {} |", code_list(&equality::attributes(own), false));
    }
}

/// `a`, `b`, … (as elements `<a>` when `elements`).
fn code_list(names: &[&str], elements: bool) -> String {
    let quoted: Vec<String> =
        names.iter().map(|n| if elements { format!("`<{n}>`") } else { format!("`{n}`") }).collect();
    quoted.join(", ")
}
