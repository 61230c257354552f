//! The MJCF importer and the model compiler on arbitrary text: an error,
//! never a panic. Seeds: examples/ and tests/fixtures/mjcf/.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(xml) = std::str::from_utf8(data) else { return };
    if let Ok(imported) = nudyn::mjcf::parse_mjcf(xml) {
        let _ = nudyn::model::Model::compile(&imported.vehicle);
    }
});
