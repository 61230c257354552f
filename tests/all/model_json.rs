//! The compiled model is what an FMU loads from its resources: its JSON
//! form must read back to the identical model.

use crate::common::{Rng, TreeOptions, random_vehicle};
use nudyn::model::Model;

#[test]
fn compiled_model_round_trips_through_json_exactly() {
    let mut rng = Rng::new(99);
    let vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 12, free_base: true, passive: true, chain: false });
    let model = Model::compile(&vehicle).unwrap();
    let json = serde_json::to_string(&model).unwrap();
    let back: Model = serde_json::from_str(&json).unwrap();
    assert_eq!(back, model);
}

#[test]
fn every_example_compiles_and_round_trips() {
    let examples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut count = 0;
    for entry in std::fs::read_dir(examples).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "xml") {
            let imported = nudyn::mjcf::load_mjcf(&path).unwrap();
            let model = Model::compile(&imported.vehicle).unwrap();
            let back: Model = serde_json::from_str(&serde_json::to_string(&model).unwrap()).unwrap();
            assert_eq!(back, model, "{}", path.display());
            count += 1;
        }
    }
    assert!(count >= 4, "expected the bundled examples, found {count}");
}

/// A model file whose force sensors would read outside it (a body index
/// past the bodies, an equality without its bodies) is refused by the
/// loader's check, never read at a wrong address.
#[test]
fn a_model_whose_force_sensors_name_missing_bodies_is_refused() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/constraints/docked_servicer.xml");
    let model = Model::compile(&nudyn::mjcf::load_mjcf(&path).unwrap().vehicle).unwrap();
    assert_eq!(model.validate(), Ok(()));
    assert_eq!(model.interaction_bodies.equalities.len(), model.constraints.equalities.len());
    let mut past_the_bodies = model.clone();
    past_the_bodies.interaction_bodies.equalities[0][1] = Some(model.body_masses.len());
    let refused = past_the_bodies.validate().unwrap_err().to_string();
    assert!(refused.contains("reads outside the model"), "{refused}");
    let mut unpaired = model.clone();
    unpaired.interaction_bodies.equalities.pop();
    let refused = unpaired.validate().unwrap_err().to_string();
    assert!(refused.contains("bodies of every equality"), "{refused}");
    let mut wrench_on_nothing = model;
    wrench_on_nothing.interaction_bodies.wrench_inputs.push(0);
    assert!(wrench_on_nothing.validate().is_err());
}

/// A model file whose tendon armature terms are not those of its tendons
/// (a term moved to another dof, a weight changed, the armature negative)
/// is refused by the loader's check: the terms index the workspace's buffers.
#[test]
fn a_model_whose_tendon_armature_terms_were_edited_is_refused() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/tendons/tendon_armature.xml");
    let model = Model::compile(&nudyn::mjcf::load_mjcf(&path).unwrap().vehicle).unwrap();
    assert_eq!(model.validate(), Ok(()));
    let mut moved = model.clone();
    moved.tendon_inertia[0].dof = model.nv;
    assert_eq!(moved.validate(), Err(nudyn::model::InvalidModel::TendonInertia));
    let mut reweighted = model.clone();
    reweighted.tendon_inertia[1].weight *= 2.0;
    assert_eq!(reweighted.validate(), Err(nudyn::model::InvalidModel::TendonInertia));
    let mut negative = model;
    negative.tendons[0].armature = -1.0;
    let refused = negative.validate().unwrap_err().to_string();
    assert!(refused.contains("armature is negative"), "{refused}");
}
