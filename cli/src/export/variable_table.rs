//! The plant's variables as a Markdown table, rendered from the contract's
//! layout: docs/fmi.md shows it for `examples/bus_arm7.xml`, and a test
//! keeps the page equal to it (`NUDYN_WRITE_DOCS=1` rewrites the section).

use nudyn_contract::blocks::Shape;
use nudyn_contract::fmi3::{Fmi3Variables, TIME_VR};
use nudyn_contract::plant::{ENERGY_PROJECTION_NAME, ENERGY_PROJECTION_VR, METHOD_NAME, METHOD_VR, PlantResource};
use nudyn_contract::resource::Resource;
use nudyn_contract::variable::{Causality, Kind, Variability};

/// "a" or "a–b", for a range of value references.
fn range(first: u32, len: usize) -> String {
    if len == 1 { first.to_string() } else { format!("{first}–{}", first + len as u32 - 1) }
}

fn nature(kind: Kind) -> String {
    let causality = match kind.causality {
        Causality::Parameter => "parameter",
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Local => "local",
    };
    let variability = match kind.variability {
        Variability::Fixed => "fixed",
        Variability::Tunable => "tunable",
        Variability::Continuous => "continuous",
    };
    let initial = match kind.causality {
        Causality::Input => "",
        Causality::Parameter => ", exact",
        _ if kind.exact_start => ", exact",
        _ => ", calculated",
    };
    format!("{causality}, {variability}{initial}")
}

/// The table of the plant FMU of `resource`: per variable its FMI 2.0
/// name(s) and value references, its FMI 3.0 value reference with arrays
/// and with `--fmi3-scalars`, and its causality, variability and initial.
pub fn markdown(resource: &PlantResource) -> String {
    let layout = resource.layout();
    // The FMI 3.0 tables the FMU serves, with arrays and with scalars.
    let with_scalars = |fmi3_scalars| PlantResource { fmi3_scalars, ..resource.clone() }.fmi3_variables();
    let (arrays, scalars) = (with_scalars(false), with_scalars(true));
    let fmi3 = |table: &Fmi3Variables, name: &str| table.value_reference(name).expect("named in the table");
    let mut text = String::from(
        "| FMI 2.0 name | FMI 2.0 type, vr | FMI 3.0 vr | FMI 3.0 vr, `--fmi3-scalars` | causality, variability, initial |\n\
         |---|---|---|---|---|\n",
    );
    text += &format!("| `time` | | {TIME_VR} | {TIME_VR} | independent |\n");
    text += &format!(
        "| `{METHOD_NAME}` | Integer, {METHOD_VR} | {} | {} | parameter, fixed, exact |\n",
        fmi3(&arrays, METHOD_NAME),
        fmi3(&scalars, METHOD_NAME)
    );
    text += &format!(
        "| `{ENERGY_PROJECTION_NAME}` | Boolean, {ENERGY_PROJECTION_VR} | {} | {} | parameter, fixed, exact |\n",
        fmi3(&arrays, ENERGY_PROJECTION_NAME),
        fmi3(&scalars, ENERGY_PROJECTION_NAME)
    );
    for block in layout.real_blocks().iter().filter(|block| block.len > 0) {
        let kind = layout.element(block.first).map_or(Kind::INPUT, |element| element.kind());
        let name = match block.shape {
            Shape::Scalar => block.name.to_string(),
            Shape::Array => format!("{}[1..{}]", block.name, block.len),
            Shape::Derivative => format!("der({}[1..{}])", block.name, block.len),
        };
        let first_element = block.element_name(0);
        text += &format!(
            "| `{name}` | Real, {} | {} | {} | {} |\n",
            range(block.first, block.len),
            fmi3(&arrays, &block.array_name()),
            range(fmi3(&scalars, &first_element), block.len),
            nature(kind)
        );
    }
    text
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use nudyn::model::Model;

    use super::*;

    const BEGIN: &str = "<!-- generated from the contract's layout (cli/src/export/variable_table.rs): begin -->\n";
    const END: &str = "<!-- generated: end -->\n";

    #[test]
    fn docs_fmi_md_shows_the_layouts_table() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let imported = nudyn::mjcf::load_mjcf(&root.join("examples/bus_arm7.xml")).expect("the example imports");
        let model = Model::compile(&imported.vehicle).expect("the example compiles");
        let outputs = "qvel,kinetic_energy,power,momentum,qfrc_constraint".parse().expect("known outputs");
        let generated = markdown(&PlantResource::new(model, outputs));

        let path = root.join("docs/fmi.md");
        let page = std::fs::read_to_string(&path).expect("docs/fmi.md");
        let start = page.find(BEGIN).expect("docs/fmi.md has the generated section") + BEGIN.len();
        let end = start + page[start..].find(END).expect("the generated section ends");
        if std::env::var_os("NUDYN_WRITE_DOCS").is_some() {
            std::fs::write(&path, format!("{}{generated}{}", &page[..start], &page[end..])).expect("write docs/fmi.md");
            return;
        }
        assert!(
            page[start..end] == generated,
            "docs/fmi.md's variable table differs from the layout's: rerun with NUDYN_WRITE_DOCS=1 \
             cargo test --release -p nudyn-cli --lib variable_table, and commit the file"
        );
    }
}
