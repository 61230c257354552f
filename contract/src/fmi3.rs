//! The FMI 3.0 view of a nudyn FMU's variables.
//!
//! FMI 2.0 has scalar variables only, so the contract numbers scalars
//! (`theta[3]` is one value reference). FMI 3.0 has arrays: an array block
//! of the layout ([`RealBlock`]), the scalars `base[1]` … `base[n]`,
//! becomes the 1-D array `base` with one value reference (`der(theta[k])`
//! becomes `der(theta)`), and a scalar stays a scalar; for hosts that read
//! no arrays (OMSimulator, PyFMI), an FMU exported with `--fmi3-scalars`
//! declares every element as a scalar under its FMI 2.0 name. The FMI 3.0 exporter and the FMI 3.0 layer of the binary both
//! read this one table, so the modelDescription and the binary cannot
//! disagree; the binary translates each FMI 3.0 value reference into the
//! FMI 2.0 value references of its elements and runs the same checks and
//! the same component.
//!
//! FMI 3.0 value references are unique across types (FMI 2.0's are per
//! type): 0 is `time`, the independent variable; then the enumerations, the
//! Booleans and the Float64 variables follow in the FMI 2.0 order.

use crate::blocks::{RealBlock, Shape};

/// The value reference of `time`, the independent variable.
pub const TIME_VR: u32 = 0;

/// The name of the independent variable.
pub const TIME_NAME: &str = "time";

/// The FMI 3.0 type of a variable, of those nudyn uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueType {
    /// `<Float64>`: an FMI 2.0 Real.
    Float64,
    /// `<Enumeration>` (read and written as Int64): an FMI 2.0 Integer enumeration.
    Enumeration,
    /// `<Boolean>`.
    Boolean,
}

impl ValueType {
    /// The FMI 3.0 type name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            ValueType::Float64 => "Float64",
            ValueType::Enumeration => "Enumeration",
            ValueType::Boolean => "Boolean",
        }
    }
}

/// One FMI 3.0 variable: a scalar, or a 1-D array of consecutive FMI 2.0 scalars.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fmi3Variable {
    /// Its FMI 3.0 value reference.
    pub value_reference: u32,
    /// Its name: `theta`, `kinetic_energy`, `der(nu)`.
    pub name: String,
    /// Its type.
    pub value_type: ValueType,
    /// The FMI 2.0 value reference of its first element; the others follow.
    pub first: u32,
    /// The number of elements (1 for a scalar).
    pub len: usize,
    /// Whether it is an array (declared with a `<Dimension>`), even of one element.
    pub array: bool,
    /// The FMI 3.0 value reference of the state it is the time derivative of, if it is one.
    pub derivative_of: Option<u32>,
}

impl Fmi3Variable {
    /// The FMI 2.0 value references of its elements, in order.
    pub fn elements(&self) -> impl Iterator<Item = u32> + use<> {
        self.first..self.first + self.len as u32
    }
}

/// Every FMI 3.0 variable of an FMU but `time`, by value reference.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Fmi3Variables {
    /// Position i holds value reference i + 1.
    variables: Vec<Fmi3Variable>,
}

/// One dependency of an element of an unknown on an element of a known, as
/// fmi3GetVariableDependencies reports it: element indices are 1-based for
/// arrays and 0 for scalars.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ElementDependency {
    /// The element of the unknown.
    pub element: usize,
    /// The known's FMI 3.0 value reference.
    pub known: u32,
    /// The element of the known.
    pub known_element: usize,
}

impl Fmi3Variables {
    /// The table of an FMU with FMI 2.0 variables `enumerations` and
    /// `booleans`, each as (value reference, name) in value-reference order,
    /// and the Real variables' numbered `blocks`: each array block one
    /// array, or with `scalars` (`--fmi3-scalars`, for hosts without
    /// arrays) each element one scalar named as in FMI 2.0.
    pub fn new(
        enumerations: impl IntoIterator<Item = (u32, String)>,
        booleans: impl IntoIterator<Item = (u32, String)>,
        blocks: impl IntoIterator<Item = RealBlock>,
        scalars: bool,
    ) -> Self {
        let mut variables: Vec<Fmi3Variable> = Vec::new();
        let scalar = |value_type, (vr, name): (u32, String)| Fmi3Variable {
            value_reference: 0,
            name,
            value_type,
            first: vr,
            len: 1,
            array: false,
            derivative_of: None,
        };
        variables.extend(enumerations.into_iter().map(|v| scalar(ValueType::Enumeration, v)));
        variables.extend(booleans.into_iter().map(|v| scalar(ValueType::Boolean, v)));
        // States come before their derivatives: a derivative's state is found among those already listed.
        let position_of =
            |variables: &[Fmi3Variable], name: &str| variables.iter().position(|v| v.name == name).map(|p| p as u32);
        for block in blocks.into_iter().filter(|block| block.len > 0) {
            if scalars || block.shape == Shape::Scalar {
                for k in 0..block.len {
                    let state = (block.shape == Shape::Derivative)
                        .then(|| position_of(&variables, &format!("{}[{}]", block.name, k + 1)))
                        .flatten();
                    let mut element = scalar(ValueType::Float64, (block.first + k as u32, block.element_name(k)));
                    element.derivative_of = state;
                    variables.push(element);
                }
            } else {
                let state = (block.shape == Shape::Derivative).then(|| position_of(&variables, block.name)).flatten();
                variables.push(Fmi3Variable {
                    value_reference: 0,
                    name: block.array_name(),
                    value_type: ValueType::Float64,
                    first: block.first,
                    len: block.len,
                    array: true,
                    derivative_of: state,
                });
            }
        }
        // Positions become value references: 0 is time.
        let value_reference_at = |position: usize| TIME_VR + 1 + position as u32;
        for (i, variable) in variables.iter_mut().enumerate() {
            variable.value_reference = value_reference_at(i);
            variable.derivative_of = variable.derivative_of.map(|position| value_reference_at(position as usize));
        }
        Fmi3Variables { variables }
    }

    /// The element index fmi3GetVariableDependencies gives element `k` (0-based) of `variable`.
    fn element_index(variable: &Fmi3Variable, k: usize) -> usize {
        if variable.array { k + 1 } else { 0 }
    }

    /// The dependencies of the unknown with FMI 3.0 value reference `vr`,
    /// element by element, where `dependencies(e)` lists the FMI 2.0 value
    /// references of the knowns of the FMI 2.0 Real `e` (the contract's
    /// `Resource::dependencies`); `None` if it is not an unknown (an output
    /// or a state derivative). Computed when asked: a table of every
    /// element's knowns grows with the square of the vehicle's size.
    pub fn element_dependencies(
        &self,
        vr: u32,
        dependencies: impl Fn(u32) -> Option<Vec<u32>>,
    ) -> Option<Vec<ElementDependency>> {
        let unknown = self.get(vr).filter(|v| v.value_type == ValueType::Float64)?;
        let mut list = Vec::new();
        for (k, element) in unknown.elements().enumerate() {
            for known in dependencies(element)? {
                let (variable, j) = self.real_element(known)?;
                list.push(ElementDependency {
                    element: Self::element_index(unknown, k),
                    known: variable.value_reference,
                    known_element: Self::element_index(variable, j),
                });
            }
        }
        Some(list)
    }

    /// The FMI 3.0 value references of the knowns of the unknown `vr`, ascending.
    pub fn known_variables(&self, vr: u32, dependencies: impl Fn(u32) -> Option<Vec<u32>>) -> Option<Vec<u32>> {
        let elements = self.element_dependencies(vr, dependencies)?;
        let mut knowns: Vec<u32> = elements.into_iter().map(|d| d.known).collect();
        knowns.sort_unstable();
        knowns.dedup();
        Some(knowns)
    }

    /// The variable with FMI 3.0 value reference `vr` (`time` is not in the table).
    pub fn get(&self, vr: u32) -> Option<&Fmi3Variable> {
        usize::try_from(vr.checked_sub(TIME_VR + 1)?).ok().and_then(|i| self.variables.get(i))
    }

    /// Every variable, in value-reference order.
    pub fn iter(&self) -> impl Iterator<Item = &Fmi3Variable> {
        self.variables.iter()
    }

    /// The Float64 variable holding the FMI 2.0 Real `vr`, and the 0-based element index.
    pub fn real_element(&self, vr: u32) -> Option<(&Fmi3Variable, usize)> {
        self.variables
            .iter()
            .filter(|v| v.value_type == ValueType::Float64)
            .find(|v| vr >= v.first && ((vr - v.first) as usize) < v.len)
            .map(|v| (v, (vr - v.first) as usize))
    }

    /// The FMI 3.0 value reference of the variable named `name`.
    pub fn value_reference(&self, name: &str) -> Option<u32> {
        self.variables.iter().find(|v| v.name == name).map(|v| v.value_reference)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn named(vr: u32, name: &str) -> (u32, String) {
        (vr, name.to_string())
    }

    fn block(name: &'static str, shape: Shape, first: u32, len: usize) -> RealBlock {
        RealBlock { name, shape, first, len }
    }

    /// Reals 1 to 9: tolerance, eps[1..2], theta[1], kinetic_energy,
    /// der(theta[1]), target_position[1..2], target_quaternion[1]; an empty
    /// array between them.
    fn blocks() -> Vec<RealBlock> {
        vec![
            block("tolerance", Shape::Scalar, 1, 1),
            block("eps", Shape::Array, 2, 2),
            block("ctrl", Shape::Array, 4, 0),
            block("theta", Shape::Array, 4, 1),
            block("kinetic_energy", Shape::Scalar, 5, 1),
            block("theta", Shape::Derivative, 6, 1),
            block("target_position", Shape::Array, 7, 2),
            block("target_quaternion", Shape::Array, 9, 1),
        ]
    }

    #[test]
    fn array_blocks_become_arrays() {
        let table = Fmi3Variables::new([named(0, "method")], [named(0, "energy_projection")], blocks(), false);
        // (value reference, name, type, first, len, array, derivative_of)
        type Summary<'a> = (u32, &'a str, ValueType, u32, usize, bool, Option<u32>);
        let summary: Vec<Summary> = table
            .iter()
            .map(|v| (v.value_reference, v.name.as_str(), v.value_type, v.first, v.len, v.array, v.derivative_of))
            .collect();
        use ValueType::*;
        assert_eq!(
            summary,
            [
                (1, "method", Enumeration, 0, 1, false, None),
                (2, "energy_projection", Boolean, 0, 1, false, None),
                (3, "tolerance", Float64, 1, 1, false, None),
                (4, "eps", Float64, 2, 2, true, None),
                (5, "theta", Float64, 4, 1, true, None),
                (6, "kinetic_energy", Float64, 5, 1, false, None),
                (7, "der(theta)", Float64, 6, 1, true, Some(5)),
                (8, "target_position", Float64, 7, 2, true, None),
                (9, "target_quaternion", Float64, 9, 1, true, None),
            ]
        );
        assert_eq!(table.get(TIME_VR), None);
        assert_eq!(table.get(4).map(|v| v.name.as_str()), Some("eps"));
        assert_eq!(table.get(10), None);
        assert_eq!(table.real_element(3).map(|(v, k)| (v.value_reference, k)), Some((4, 1)));
        assert_eq!(table.real_element(0), None, "FMI 2.0 Real vr 0 does not exist here");
        assert_eq!(table.value_reference("der(theta)"), Some(7));

        // kinetic_energy (Real 5) depends on eps[2] (Real 3) and tolerance (Real 1), say.
        let dependencies = |vr| (vr == 5).then(|| vec![1, 3]);
        let expected = [
            ElementDependency { element: 0, known: 3, known_element: 0 },
            ElementDependency { element: 0, known: 4, known_element: 2 },
        ];
        assert_eq!(table.element_dependencies(6, dependencies), Some(expected.to_vec()));
        assert_eq!(table.known_variables(6, dependencies), Some(vec![3, 4]));
        assert_eq!(table.element_dependencies(4, dependencies), None, "an input is no unknown");
    }

    #[test]
    fn with_scalars_every_element_is_a_scalar_named_as_in_fmi2() {
        let table = Fmi3Variables::new([named(0, "method")], [], blocks(), true);
        let summary: Vec<(u32, &str, u32, bool, Option<u32>)> =
            table.iter().map(|v| (v.value_reference, v.name.as_str(), v.first, v.array, v.derivative_of)).collect();
        assert_eq!(
            summary,
            [
                (1, "method", 0, false, None),
                (2, "tolerance", 1, false, None),
                (3, "eps[1]", 2, false, None),
                (4, "eps[2]", 3, false, None),
                (5, "theta[1]", 4, false, None),
                (6, "kinetic_energy", 5, false, None),
                (7, "der(theta[1])", 6, false, Some(5)),
                (8, "target_position[1]", 7, false, None),
                (9, "target_position[2]", 8, false, None),
                (10, "target_quaternion[1]", 9, false, None),
            ]
        );
        assert!(table.iter().all(|v| v.len == 1));
        // Each element's own variable, element index 0 as for any scalar.
        let dependencies = |vr| (vr == 5).then(|| vec![1, 3]);
        let expected = [
            ElementDependency { element: 0, known: 2, known_element: 0 },
            ElementDependency { element: 0, known: 4, known_element: 0 },
        ];
        assert_eq!(table.element_dependencies(6, dependencies), Some(expected.to_vec()));
    }
}
