//! docs/mjcf-support.md is the table `nudyn::mjcf::support_table` renders
//! from the importer's own lists: this test fails when they drift apart.
//! `NUDYN_WRITE_DOCS=1` rewrites the file instead.

use std::path::Path;

use nudyn::mjcf::support_table;

#[test]
fn mjcf_support_table_is_the_importers() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/mjcf-support.md");
    let generated = support_table();
    if std::env::var_os("NUDYN_WRITE_DOCS").is_some() {
        std::fs::write(&path, &generated).expect("write docs/mjcf-support.md");
        return;
    }
    let written = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        written == generated,
        "docs/mjcf-support.md differs from the importer's lists: rerun with NUDYN_WRITE_DOCS=1 \
         cargo test --release -p nudyn --test mjcf_support, and commit the file"
    );
}

#[test]
fn the_table_names_what_the_importer_refuses_and_reads() {
    let table = support_table();
    // A refusal of each kind, with the importer's reason, and a read element.
    for line in [
        "| `<attach>` | attaching another model |",
        "| `<actuator>/<muscle>` | muscle actuators (activation dynamics and muscle force curves) |",
        "| `<sensor>/<camprojection>` | the sensor type is not computed by nudyn |",
        "| `<extension>` | ignored with a warning |",
    ] {
        assert!(table.contains(line), "missing: {line}");
    }
    assert!(table.contains("| `<body>` | `name`, `childclass`, `pos`"));
}
