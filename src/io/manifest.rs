//! The shard record a sweep writes into its `summary.json` (`"shard"`), so that merging
//! can tell a complete set of shards from one with a shard missing, repeated, cut short or
//! taken from another sweep.

use serde::{Deserialize, Serialize};

use crate::sweep::engine::{render_value, Case};

/// What one sweep run covered.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardManifest {
    /// This shard, 1-based (1 for an unsharded sweep).
    pub index: usize,
    /// Number of shards the sweep was split into.
    pub count: usize,
    /// Cases in the whole sweep.
    pub cases_total: usize,
    /// Cases this shard owns (rows its table has when complete).
    pub cases_in_shard: usize,
    /// Checksum of the whole sweep's case list (indices, keys, values): equal for shards
    /// of one sweep, different for another grid, seed or sample count.
    pub case_list_checksum: String,
}

/// 64-bit FNV-1a: stable across versions and platforms, enough to tell sweeps apart.
fn fnv1a(bytes: impl IntoIterator<Item = u8>, mut h: u64) -> u64 {
    for b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

/// Checksum of a case list, as hex.
pub fn case_list_checksum(cases: &[Case]) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325;
    for c in cases {
        h = fnv1a(format!("{}\n", c.index).into_bytes(), h);
        for (key, _, value) in &c.assignments {
            h = fnv1a(format!("{key}={}\n", render_value(value)).into_bytes(), h);
        }
    }
    format!("{h:016x}")
}

impl ShardManifest {
    /// The record of shard `k` of `n` over `cases`.
    pub fn new(cases: &[Case], k: usize, n: usize) -> ShardManifest {
        ShardManifest {
            index: k,
            count: n,
            cases_total: cases.len(),
            cases_in_shard: cases.iter().filter(|c| c.index % n == k - 1).count(),
            case_list_checksum: case_list_checksum(cases),
        }
    }

    /// Read the record from a sweep's `summary.json` text; `None` when it holds none.
    pub fn from_summary(text: &str) -> Option<ShardManifest> {
        let v: serde_json::Value = serde_json::from_str(text).ok()?;
        serde_json::from_value(v.get("shard")?.clone()).ok()
    }

    /// Whether the shard owns case `index`.
    pub fn owns(&self, index: usize) -> bool {
        self.count > 0 && index % self.count + 1 == self.index
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn case(index: usize, v: f64) -> Case {
        Case {
            index,
            assignments: vec![("drive.preload_n".into(), "preload_n".into(), v.into())],
        }
    }

    #[test]
    fn checksum_tells_case_lists_apart() {
        let a = vec![case(0, 1.0), case(1, 2.0)];
        let b = vec![case(0, 1.0), case(1, 2.5)];
        assert_eq!(case_list_checksum(&a), case_list_checksum(&a.clone()));
        assert_ne!(case_list_checksum(&a), case_list_checksum(&b));
        assert_ne!(case_list_checksum(&a), case_list_checksum(&a[..1]));
        let m = ShardManifest::new(&a, 2, 2);
        assert_eq!(m.cases_in_shard, 1);
        assert!(m.owns(1) && !m.owns(0));
        let text = serde_json::json!({ "shard": m }).to_string();
        assert_eq!(ShardManifest::from_summary(&text), Some(m));
    }
}
