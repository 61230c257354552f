//! The resource file an FMU ships (`resources/model.json` for the plant,
//! `resources/controller.json` for the controller) and the GUID derived
//! from it: the FMU recomputes the GUID from the resource it loads and the
//! variables it serves, so a GUID that does not match fails instantiation.

use serde::Serialize;
use serde::de::DeserializeOwned;
use sha2::{Digest, Sha256};

use nudyn::model::Model;

use crate::blocks::RealBlock;
use crate::fmi3::Fmi3Variables;

/// A resource file of a nudyn FMU.
pub trait Resource: Serialize + DeserializeOwned {
    /// Its file name in the FMU's `resources/` directory.
    const FILE: &'static str;
    /// The layout version the writer uses and the reader accepts, raised
    /// whenever the file gains something an older reader would silently drop
    /// or replace by a default (what each version added is in git's history).
    const FORMAT: u32;

    /// The version the file was written with.
    fn format(&self) -> u32;

    /// The compiled vehicle it holds.
    fn model(&self) -> &Model;

    /// The FMU's Real variables as numbered blocks, in value-reference order.
    fn real_blocks(&self) -> Vec<RealBlock>;

    /// Whether its FMI 3.0 variables are all scalars (`--fmi3-scalars`), for
    /// hosts without arrays.
    fn fmi3_scalars(&self) -> bool;

    /// The FMU's Real variables (FMI 2.0 value reference, name) in value-reference order.
    fn variable_names(&self) -> Vec<(u32, String)> {
        self.real_blocks().iter().flat_map(RealBlock::elements).collect()
    }

    /// The FMI 2.0 Integer enumeration variables (value reference, name).
    fn enumerations(&self) -> Vec<(u32, String)> {
        Vec::new()
    }

    /// The FMI 2.0 Boolean variables (value reference, name).
    fn booleans(&self) -> Vec<(u32, String)> {
        Vec::new()
    }

    /// The knowns (states and inputs, by FMI 2.0 Real value reference,
    /// ascending) the output or state derivative `vr` depends on; `None`
    /// for a variable that is neither.
    fn dependencies(&self, vr: u32) -> Option<Vec<u32>>;

    /// The FMU's variables as FMI 3.0 declares them.
    fn fmi3_variables(&self) -> Fmi3Variables {
        Fmi3Variables::new(self.enumerations(), self.booleans(), self.real_blocks(), self.fmi3_scalars())
    }

    /// Its bytes as written into the FMU.
    fn to_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        serde_json::to_vec(self)
    }

    /// The path of the file inside the FMU archive.
    fn archive_path() -> String {
        format!("resources/{}", Self::FILE)
    }

    /// The GUID of an FMU whose resource file has `bytes` (which parse to `self`).
    fn guid(&self, bytes: &[u8]) -> String {
        guid_of(bytes, self.variable_names().into_iter())
    }
}

/// A SHA-256 of the resource file's bytes and of its FMU's (value
/// reference, name) list, written as a braced UUID.
pub fn guid_of(resource_json: &[u8], variables: impl Iterator<Item = (u32, String)>) -> String {
    let mut hasher = Sha256::new();
    hasher.update(resource_json);
    for (vr, name) in variables {
        hasher.update(format!("\n{vr} {name}").as_bytes());
    }
    let hex: String = hasher.finalize()[..16].iter().map(|b| format!("{b:02x}")).collect();
    format!("{{{}-{}-{}-{}-{}}}", &hex[0..8], &hex[8..12], &hex[12..16], &hex[16..20], &hex[20..32])
}
