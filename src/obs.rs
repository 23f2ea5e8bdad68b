//! Observation layouts: an observation is one flat `f32` vector made of named blocks (`ir`,
//! `goal_distance`, ...), each with its bounds. A task declares its agents' own blocks once
//! (`TaskKind::agents` puts a robot's observed sensor blocks before them), the batch builds the
//! joint layout from them, the binding exports it (`obs_layout`), and controllers find the
//! slices they read by name. Nothing else restates where a value sits.
//!
//! Units are each block's (see the task's manual); bounds are what the observation space says.

use std::ops::Range;

use crate::error::{Error, Result};

/// One named block of an observation, with its bounds per value.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// Its name (`"ir"`, `"goal_distance"`; with several agents `"follower_0/ir"`).
    pub name: String,
    /// Lowest value of each element.
    pub low: Vec<f32>,
    /// Highest value of each element.
    pub high: Vec<f32>,
}

impl Block {
    /// A block of `len` values all in `[low, high]`.
    pub fn new(name: &str, len: usize, low: f32, high: f32) -> Self {
        Self {
            name: name.to_string(),
            low: vec![low; len],
            high: vec![high; len],
        }
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.low.len()
    }

    /// Whether the block has no values.
    pub fn is_empty(&self) -> bool {
        self.low.is_empty()
    }
}

/// The blocks of an observation, in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObsLayout {
    blocks: Vec<Block>,
}

impl ObsLayout {
    /// A layout of `blocks` in order.
    pub fn new(blocks: Vec<Block>) -> Self {
        Self { blocks }
    }

    /// The blocks, in order.
    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }

    /// Total number of values.
    pub fn len(&self) -> usize {
        self.blocks.iter().map(Block::len).sum()
    }

    /// Whether the layout has no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends the blocks of `other`, their names prefixed with `prefix/` when `prefix` is given.
    pub fn extend(&mut self, other: &ObsLayout, prefix: Option<&str>) {
        for block in &other.blocks {
            let mut block = block.clone();
            if let Some(prefix) = prefix {
                block.name = format!("{prefix}/{}", block.name);
            }
            self.blocks.push(block);
        }
    }

    /// Every block as (name, start..stop), in order.
    pub fn slices(&self) -> Vec<(String, Range<usize>)> {
        let mut start = 0;
        self.blocks
            .iter()
            .map(|b| {
                let range = start..start + b.len();
                start = range.end;
                (b.name.clone(), range)
            })
            .collect()
    }

    /// The slice of block `name`, if the layout has it.
    pub fn find(&self, name: &str) -> Option<Range<usize>> {
        self.slices()
            .into_iter()
            .find(|(n, _)| n == name)
            .map(|(_, r)| r)
    }

    /// The first index of block `name`, which must hold `len` values; `who` (a controller's
    /// name) is named in the error.
    pub fn require(&self, name: &str, len: usize, who: &str) -> Result<usize> {
        match self.find(name) {
            Some(range) if range.len() == len => Ok(range.start),
            Some(range) => Err(Error::config(
                who,
                name,
                format!(
                    "this observation's `{name}` block has {} values, {who} reads {len}",
                    range.len()
                ),
            )),
            None => {
                let known: Vec<&str> = self.blocks.iter().map(|b| b.name.as_str()).collect();
                Err(Error::config(
                    who,
                    name,
                    format!(
                        "{who} reads the observation block `{name}`, which this observation \
                         lacks (it has {known:?}); observe the sensor or task value it needs"
                    ),
                ))
            }
        }
    }

    /// (low, high) of every value, in order.
    pub fn bounds(&self) -> (Vec<f32>, Vec<f32>) {
        let low = self.blocks.iter().flat_map(|b| b.low.iter().copied());
        let high = self.blocks.iter().flat_map(|b| b.high.iter().copied());
        (low.collect(), high.collect())
    }
}

/// Writes an observation block after block, in the order of its layout.
pub struct ObsWriter<'a> {
    out: &'a mut [f32],
    at: usize,
}

impl<'a> ObsWriter<'a> {
    /// A writer at the start of `out`.
    pub fn new(out: &'a mut [f32]) -> Self {
        Self { out, at: 0 }
    }

    /// Writes one value.
    #[inline]
    pub fn put(&mut self, value: f32) {
        self.out[self.at] = value;
        self.at += 1;
    }

    /// The next `len` values, to fill in place.
    #[inline]
    pub fn take(&mut self, len: usize) -> &mut [f32] {
        let start = self.at;
        self.at += len;
        &mut self.out[start..self.at]
    }

    /// Values written so far.
    pub fn position(&self) -> usize {
        self.at
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slices_are_contiguous_and_named() {
        let mut layout = ObsLayout::new(vec![Block::new("ir", 8, 0.0, 1.0)]);
        layout.extend(
            &ObsLayout::new(vec![Block::new("goal_distance", 1, 0.0, 3.0)]),
            None,
        );
        assert_eq!(layout.len(), 9);
        assert_eq!(layout.find("goal_distance"), Some(8..9));
        assert_eq!(layout.require("ir", 8, "test").expect("ir"), 0);
        let e = layout.require("us", 5, "VFH").unwrap_err().to_string();
        assert!(e.contains("`us`") && e.contains("VFH"), "{e}");
        let mut joint = ObsLayout::default();
        joint.extend(&layout, Some("robot_0"));
        assert_eq!(joint.find("robot_0/ir"), Some(0..8));
    }
}
