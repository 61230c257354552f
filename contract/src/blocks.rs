//! Value references numbered block by block: a layout is a list of blocks
//! (a variable kind and how many of it), numbered consecutively, so that
//! decoding a value reference and listing the variables share one order.

/// The variable of index k within a block of variables of type V.
pub(crate) type VariableOf<V> = fn(usize) -> V;

/// Blocks of variables numbered consecutively from value reference `first`:
/// (length, variable of index k) becomes (first value reference, length,
/// variable of index k).
pub(crate) fn numbered_blocks<V, const N: usize>(
    first: u32,
    blocks: [(usize, VariableOf<V>); N],
) -> impl Iterator<Item = (u32, usize, VariableOf<V>)> {
    let mut next = first;
    blocks.into_iter().map(move |(len, variable)| {
        let first = next;
        next += len as u32;
        (first, len, variable)
    })
}

/// The variable with value reference `vr` among numbered `blocks`, if any.
pub(crate) fn variable_at<V>(mut blocks: impl Iterator<Item = (u32, usize, VariableOf<V>)>, vr: u32) -> Option<V> {
    blocks
        .find(|&(first, len, _)| vr >= first && ((vr - first) as usize) < len)
        .map(|(first, _, variable)| variable((vr - first) as usize))
}

/// Every variable of numbered `blocks` with its value reference, in order.
pub(crate) fn every_variable<V>(
    blocks: impl Iterator<Item = (u32, usize, VariableOf<V>)>,
) -> impl Iterator<Item = (u32, V)> {
    blocks.flat_map(|(first, len, variable)| (0..len).map(move |k| (first + k as u32, variable(k))))
}
