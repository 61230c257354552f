//! Loading an FMU's resources at instantiation: the resource file read,
//! its format, model, law and GUID checked, and the component (plant or
//! controller) made from it, with the FMI 3.0 view of its variables.

use std::path::{Path, PathBuf};

use nudyn::model::InvalidModel;
use nudyn_contract::controller::ControllerResource;
use nudyn_contract::fmi3::Fmi3Variables;
use nudyn_contract::plant::PlantResource;
use nudyn_contract::resource::Resource;

use crate::component::Component;
use crate::controller::Controller;
use crate::plant::Plant;
use crate::uri::UriError;

/// Loads the FMU's resources from `directory`: the controller if
/// `controller.json` is there, else the plant (whose loader reports a
/// missing `model.json`); with the FMI 3.0 view of its variables.
pub fn load(directory: &Path, guid: &str) -> Result<(Box<dyn Component>, Fmi3Variables), LoadError> {
    if directory.join(ControllerResource::FILE).is_file() {
        let check_law = |resource: &ControllerResource, path: &Path| match Controller::law_mismatch(resource) {
            Some(reason) => Err(LoadError::BadLaw { path: path.to_path_buf(), reason }),
            None => Ok(()),
        };
        let Loaded { resource, path, .. } = read_resource(directory, guid, check_law)?;
        let variables = resource.fmi3_variables();
        let controller =
            Controller::new(resource).map_err(|error| LoadError::BadLaw { path, reason: error.to_string() })?;
        Ok((Box::new(controller), variables))
    } else {
        let loaded: Loaded<PlantResource> = read_resource(directory, guid, |_, _| Ok(()))?;
        let variables = loaded.resource.fmi3_variables();
        Ok((Box::new(Plant::new(loaded.resource, loaded.guid)), variables))
    }
}

/// A resource file read and checked: the format, the model's consistency,
/// what `check` checks of the rest, and the GUID (recomputed from the bytes
/// and the variables they define).
pub struct Loaded<R> {
    /// The resource.
    pub resource: R,
    /// The file it was read from.
    pub path: PathBuf,
    /// The FMU's GUID.
    pub guid: String,
}

fn read_resource<R: Resource>(
    directory: &Path,
    guid: &str,
    check: impl Fn(&R, &Path) -> Result<(), LoadError>,
) -> Result<Loaded<R>, LoadError> {
    let path = directory.join(R::FILE);
    let bytes = std::fs::read(&path).map_err(|source| LoadError::Read { path: path.clone(), source })?;
    let resource: R =
        serde_json::from_slice(&bytes).map_err(|source| LoadError::Parse { path: path.clone(), source })?;
    if resource.format() != R::FORMAT {
        return Err(LoadError::Format { path, found: resource.format(), expected: R::FORMAT });
    }
    // Before anything sized by nq or nv (the GUID's variable list, the workspace).
    resource.model().validate().map_err(|source| LoadError::BadModel { path: path.clone(), source })?;
    check(&resource, &path)?;
    let actual = resource.guid(&bytes);
    if actual != guid {
        return Err(LoadError::Guid { given: guid.to_string(), actual });
    }
    Ok(Loaded { resource, path, guid: actual })
}

/// Why fmi2Instantiate cannot make an instance.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The resource location is unusable.
    #[error(transparent)]
    Uri(#[from] UriError),
    /// The resource file cannot be read.
    #[error("cannot read the compiled model {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The resource file cannot be parsed.
    #[error("{path} is not a nudyn FMU resource: {source}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: serde_json::Error,
    },
    /// Written by an exporter with another resource format.
    #[error("{path} has resource format {found}, this binary reads format {expected}")]
    Format {
        /// The file.
        path: PathBuf,
        /// Its format.
        found: u32,
        /// The format this binary reads.
        expected: u32,
    },
    /// The compiled model is inconsistent (a corrupted or foreign resource).
    #[error("{path} does not hold a consistent compiled model: {source}")]
    BadModel {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        source: InvalidModel,
    },
    /// The controller resource holds a law that does not fit its model.
    #[error("{path} does not hold a consistent control law: {reason}")]
    BadLaw {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The GUID passed to fmi2Instantiate is not this FMU's.
    #[error("fmuGUID '{given}' does not match the FMU's resources, whose GUID is '{actual}'")]
    Guid {
        /// The GUID given.
        given: String,
        /// The GUID of the resources.
        actual: String,
    },
}
