//! Value references numbered block by block: a layout is a list of blocks
//! (a named variable of some shape and how many elements it has), numbered
//! consecutively, so that decoding a value reference, listing the
//! variables, naming them and grouping them into FMI 3.0 arrays share one
//! order and one list.

/// How the elements of a block are named and grouped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// One element named `name`.
    Scalar,
    /// Elements `name[1]` … `name[n]`: one FMI 3.0 array `name`.
    Array,
    /// Elements `der(name[1])` … `der(name[n])`, the time derivatives of
    /// the array `name`: one FMI 3.0 array `der(name)`.
    Derivative,
}

/// The variable of index k within a block of variables of type V.
pub(crate) type VariableOf<V> = fn(usize) -> V;

/// A block of a component's layout: a name, a shape, how many elements,
/// and the component's variable of each element.
pub(crate) struct Block<V> {
    pub name: &'static str,
    pub shape: Shape,
    pub len: usize,
    pub variable: VariableOf<V>,
}

/// One block of FMI 2.0 Real variables, numbered: what the FMI 3.0 table
/// and the GUID read of a component's layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RealBlock {
    /// The name (of the array whose derivatives a [`Shape::Derivative`] block holds).
    pub name: &'static str,
    /// Its shape.
    pub shape: Shape,
    /// The FMI 2.0 value reference of its first element; the others follow.
    pub first: u32,
    /// The number of elements.
    pub len: usize,
}

impl RealBlock {
    /// The FMI 2.0 name of element `k` (0-based): `name`, `name[k+1]` or `der(name[k+1])`.
    pub fn element_name(&self, k: usize) -> String {
        match self.shape {
            Shape::Scalar => self.name.to_string(),
            Shape::Array => format!("{}[{}]", self.name, k + 1),
            Shape::Derivative => format!("der({}[{}])", self.name, k + 1),
        }
    }

    /// The FMI 3.0 name of the whole block: `name` or `der(name)`.
    pub fn array_name(&self) -> String {
        match self.shape {
            Shape::Scalar | Shape::Array => self.name.to_string(),
            Shape::Derivative => format!("der({})", self.name),
        }
    }

    /// Every element's FMI 2.0 value reference and name, in order.
    pub fn elements(&self) -> impl Iterator<Item = (u32, String)> + '_ {
        (0..self.len).map(|k| (self.first + k as u32, self.element_name(k)))
    }
}

/// The variable with value reference `vr` among numbered `blocks`, if any.
pub(crate) fn variable_at<V>(mut blocks: impl Iterator<Item = (u32, Block<V>)>, vr: u32) -> Option<V> {
    blocks
        .find(|(first, block)| vr >= *first && ((vr - first) as usize) < block.len)
        .map(|(first, block)| (block.variable)((vr - first) as usize))
}

/// The value reference of `variable`, element `k` of its block, among
/// numbered `blocks`: found by the block whose element k it is, so that no
/// block number is written anywhere but in the list.
pub(crate) fn value_reference_of<V: PartialEq>(
    mut blocks: impl Iterator<Item = (u32, Block<V>)>,
    variable: V,
    k: usize,
) -> Option<u32> {
    blocks.find(|(_, block)| k < block.len && (block.variable)(k) == variable).map(|(first, _)| first + k as u32)
}

/// Every variable of numbered `blocks` with its value reference, in order.
pub(crate) fn every_variable<V>(blocks: impl Iterator<Item = (u32, Block<V>)>) -> impl Iterator<Item = (u32, V)> {
    blocks.flat_map(|(first, block)| (0..block.len).map(move |k| (first + k as u32, (block.variable)(k))))
}

/// The numbered blocks without their typed variables, for the FMI 3.0 table.
pub(crate) fn real_blocks<V>(blocks: impl Iterator<Item = (u32, Block<V>)>) -> Vec<RealBlock> {
    blocks.map(|(first, block)| RealBlock { name: block.name, shape: block.shape, first, len: block.len }).collect()
}
