//! The compiled model is what an FMU loads from its resources: its JSON
//! form must read back to the identical model.

mod common;

use common::{Rng, TreeOptions, random_vehicle};
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
