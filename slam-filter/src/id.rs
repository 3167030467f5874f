//! Feature identity: the vocabulary the state, the errors and the reports share (a leaf).

/// A feature's identity: never reused, unchanged when other features come and go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FeatureId(pub u64);
