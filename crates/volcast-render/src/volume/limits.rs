//! Resource limits checked before any voxel memory is allocated.
//!
//! Headers are untrusted: a claimed size is multiplied with `checked_mul`, compared
//! against [`Limits::max_bytes`], and readers grow their buffers only as real data
//! arrives, so a hostile header costs a few bytes, never gigabytes.

use super::VolumeError;

/// Memory limits for loading volumes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Largest voxel buffer, in bytes, that a reader may allocate.
    pub max_bytes: u64,
}

impl Default for Limits {
    /// 16 GiB, or three quarters of physical memory where that is known and smaller.
    fn default() -> Self {
        let mut max = 16u64 << 30;
        if let Some(mem) = physical_memory() {
            max = max.min(mem / 4 * 3);
        }
        Limits { max_bytes: max }
    }
}

impl Limits {
    /// Number of elements of a grid of `sizes`, and its byte count for elements of
    /// `elem_size` bytes, or an error if either overflows or exceeds the limit.
    pub fn check(&self, sizes: &[usize], elem_size: usize) -> Result<(usize, usize), VolumeError> {
        let count = sizes
            .iter()
            .try_fold(1usize, |acc, &s| acc.checked_mul(s))
            .ok_or_else(|| VolumeError::TooLarge {
                what: format!("sizes {sizes:?}"),
                bytes: None,
                limit: self.max_bytes,
            })?;
        let bytes = count
            .checked_mul(elem_size)
            .ok_or_else(|| VolumeError::TooLarge {
                what: format!("sizes {sizes:?}"),
                bytes: None,
                limit: self.max_bytes,
            })?;
        if bytes as u64 > self.max_bytes {
            return Err(VolumeError::TooLarge {
                what: format!("sizes {sizes:?}"),
                bytes: Some(bytes as u64),
                limit: self.max_bytes,
            });
        }
        Ok((count, bytes))
    }
}

/// Physical memory in bytes, from `/proc/meminfo` where it exists.
fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overflow_and_budget() {
        let l = Limits { max_bytes: 1 << 20 };
        assert!(l.check(&[4_000_000_000; 3], 1).is_err());
        assert!(l.check(&[1024, 1024, 2], 1).is_err());
        assert_eq!(l.check(&[16, 16, 16], 2).unwrap(), (4096, 8192));
    }
}
