//! Splitting a sequence between processes: `--shard K/N` takes every N-th frame of
//! the selected frames starting at the K-th (shards are numbered from 0), so N
//! processes, or the N tasks of a Slurm job array (`--shard auto`), render the
//! whole sequence between them with no overlap. Every shard computes the same grey
//! windows (from a preview of the whole orbit), so the union of the shards' images
//! is byte for byte the images of one unsharded run.

use std::fmt;
use std::ops::Range;
use std::str::FromStr;

/// The K-th of N interleaved parts of a sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// K, from 0 to `count - 1`.
    pub index: usize,
    /// N, at least 1.
    pub count: usize,
}

/// A `--shard` value that cannot be used.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ShardError {
    /// Not of the form `K/N`.
    #[error("--shard {given}: expected K/N with whole numbers 0 <= K < N (e.g. 0/4, 1/4, 2/4, 3/4), or `auto` inside a Slurm job array")]
    Syntax {
        /// What was given.
        given: String,
    },
    /// `N` is zero.
    #[error("--shard {index}/0: the number of shards N must be at least 1")]
    NoShards {
        /// K.
        index: usize,
    },
    /// `K >= N`.
    #[error("--shard {index}/{count}: shards are numbered from 0, so K must be below N (the shards of {count} are 0/{count} to {last}/{count})", last = count - 1)]
    OutOfRange {
        /// K.
        index: usize,
        /// N.
        count: usize,
    },
    /// A Slurm variable that `--shard auto` needs is not set.
    #[error("--shard auto: {var} is not set; Slurm sets it in the tasks of a job array (sbatch --array=0-3); outside Slurm use --shard K/N")]
    MissingVariable {
        /// The variable.
        var: &'static str,
    },
    /// A Slurm variable is not a whole number.
    #[error("--shard auto: {var} = `{value}` is not a whole number")]
    BadVariable {
        /// The variable.
        var: &'static str,
        /// Its value.
        value: String,
    },
    /// With `--shard auto/N`, the task ID is not a shard of `N`.
    #[error("--shard auto/{count}: SLURM_ARRAY_TASK_ID = {id} is not a shard of {count}: with auto/{count} the task ID is the shard, so submit the array as --array=0-{last} (or any part of it, such as --array={example} to render shard {example} again)", last = count - 1, example = count.saturating_sub(1).min(3))]
    TaskNotAShard {
        /// The task ID.
        id: i64,
        /// N.
        count: usize,
    },
    /// The job array's task IDs are not consecutive.
    #[error("--shard auto: the job array must have consecutive task IDs (e.g. --array=0-7 or --array=1-8, optionally with %limit), so that task IDs map to shards 0..N-1; this one has {detail}")]
    NotConsecutive {
        /// What is wrong.
        detail: String,
    },
}

impl FromStr for Shard {
    type Err = ShardError;

    /// Parses `K/N`.
    fn from_str(s: &str) -> Result<Shard, ShardError> {
        let syntax = || ShardError::Syntax {
            given: s.to_string(),
        };
        let (k, n) = s.split_once('/').ok_or_else(syntax)?;
        let index: usize = k.trim().parse().map_err(|_| syntax())?;
        let count: usize = n.trim().parse().map_err(|_| syntax())?;
        Shard::new(index, count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// Shard `index` of `count`, checked.
    pub fn new(index: usize, count: usize) -> Result<Shard, ShardError> {
        if count == 0 {
            Err(ShardError::NoShards { index })
        } else if index >= count {
            Err(ShardError::OutOfRange { index, count })
        } else {
            Ok(Shard { index, count })
        }
    }

    /// The shard of this task of a Slurm job array, from `SLURM_ARRAY_TASK_ID`,
    /// `SLURM_ARRAY_TASK_COUNT` and, when set, `SLURM_ARRAY_TASK_MIN` (the first
    /// task ID, so `--array=1-8` works as well as `--array=0-7`),
    /// `SLURM_ARRAY_TASK_MAX` and `SLURM_ARRAY_TASK_STEP` (checked to describe a
    /// consecutive array). `var` looks a variable up (`std::env::var` in the CLI).
    pub fn from_slurm(var: impl Fn(&str) -> Option<String>) -> Result<Shard, ShardError> {
        let get = |name: &'static str| -> Result<Option<i64>, ShardError> {
            match var(name) {
                None => Ok(None),
                Some(v) => v
                    .trim()
                    .parse::<i64>()
                    .map(Some)
                    .map_err(|_| ShardError::BadVariable {
                        var: name,
                        value: v.clone(),
                    }),
            }
        };
        let required = |name: &'static str| -> Result<i64, ShardError> {
            get(name)?.ok_or(ShardError::MissingVariable { var: name })
        };
        let id = required("SLURM_ARRAY_TASK_ID")?;
        let count = required("SLURM_ARRAY_TASK_COUNT")?;
        let min = get("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
        if let Some(step) = get("SLURM_ARRAY_TASK_STEP")? {
            if step != 1 {
                return Err(ShardError::NotConsecutive {
                    detail: format!("a step of {step} (SLURM_ARRAY_TASK_STEP)"),
                });
            }
        }
        if let Some(max) = get("SLURM_ARRAY_TASK_MAX")? {
            if max - min + 1 != count {
                return Err(ShardError::NotConsecutive {
                    detail: format!("{count} tasks with IDs from {min} to {max}"),
                });
            }
        }
        if count < 1 {
            return Err(ShardError::BadVariable {
                var: "SLURM_ARRAY_TASK_COUNT",
                value: count.to_string(),
            });
        }
        let index = id - min;
        if index < 0 || index >= count {
            return Err(ShardError::NotConsecutive {
                detail: format!(
                    "task ID {id} outside {min}..{} ({count} tasks)",
                    min + count - 1
                ),
            });
        }
        Shard::new(index as usize, count as usize)
    }

    /// The shard of this task of a Slurm job array of `count` shards in all
    /// (`--shard auto/N`): the index is `SLURM_ARRAY_TASK_ID` itself, whatever the
    /// array's other tasks, so `sbatch --array=3` renders exactly shard 3 of `count`
    /// again. `var` looks a variable up.
    pub fn from_slurm_of(
        count: usize,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<Shard, ShardError> {
        const VAR: &str = "SLURM_ARRAY_TASK_ID";
        let value = var(VAR).ok_or(ShardError::MissingVariable { var: VAR })?;
        let id: i64 = value.trim().parse().map_err(|_| ShardError::BadVariable {
            var: VAR,
            value: value.clone(),
        })?;
        if count == 0 {
            return Err(ShardError::NoShards { index: 0 });
        }
        match usize::try_from(id) {
            Ok(index) if index < count => Shard::new(index, count),
            _ => Err(ShardError::TaskNotAShard { id, count }),
        }
    }

    /// The frames of `range` in this shard: `start + index`, `start + index + count`, ...
    pub fn select(&self, range: Range<usize>) -> Vec<usize> {
        range
            .clone()
            .filter(|f| (f - range.start) % self.count == self.index)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let m: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| m.get(k).cloned()
    }

    #[test]
    fn parse_and_select() {
        assert_eq!("1/4".parse(), Ok(Shard { index: 1, count: 4 }));
        assert_eq!(" 0 / 1 ".parse(), Ok(Shard { index: 0, count: 1 }));
        for bad in ["", "1", "a/4", "1/b", "-1/4", "1/4/5", "1.5/4"] {
            assert!(
                matches!(bad.parse::<Shard>(), Err(ShardError::Syntax { .. })),
                "{bad}"
            );
        }
        assert_eq!(
            "4/4".parse::<Shard>(),
            Err(ShardError::OutOfRange { index: 4, count: 4 })
        );
        assert_eq!(
            "0/0".parse::<Shard>(),
            Err(ShardError::NoShards { index: 0 })
        );
        let s = Shard { index: 1, count: 3 };
        assert_eq!(s.select(0..10), vec![1, 4, 7]);
        assert_eq!(s.select(5..9), vec![6]);
        assert_eq!(
            Shard { index: 3, count: 5 }.select(0..2),
            Vec::<usize>::new()
        );
        // the shards partition the range
        let mut all: Vec<usize> = (0..4)
            .flat_map(|k| Shard { index: k, count: 4 }.select(3..20))
            .collect();
        all.sort();
        assert_eq!(all, (3..20).collect::<Vec<_>>());
        assert!(ShardError::OutOfRange { index: 4, count: 4 }
            .to_string()
            .contains("0/4 to 3/4"));
    }

    #[test]
    fn slurm_arrays_of_a_fixed_total() {
        // a resubmitted task of an 8-shard job: --array=3 is shard 3 of 8, not 0 of 1
        let s = Shard::from_slurm_of(
            8,
            env(&[
                ("SLURM_ARRAY_TASK_ID", "3"),
                ("SLURM_ARRAY_TASK_COUNT", "1"),
                ("SLURM_ARRAY_TASK_MIN", "3"),
                ("SLURM_ARRAY_TASK_MAX", "3"),
            ]),
        );
        assert_eq!(s, Ok(Shard { index: 3, count: 8 }));
        assert_eq!(
            Shard::from_slurm_of(8, env(&[("SLURM_ARRAY_TASK_ID", "0")])),
            Ok(Shard { index: 0, count: 8 })
        );
        let e = Shard::from_slurm_of(8, env(&[("SLURM_ARRAY_TASK_ID", "8")])).unwrap_err();
        assert!(e.to_string().contains("--array=0-7"), "{e}");
        assert!(matches!(
            Shard::from_slurm_of(8, env(&[("SLURM_ARRAY_TASK_ID", "-1")])),
            Err(ShardError::TaskNotAShard { .. })
        ));
        assert_eq!(
            Shard::from_slurm_of(8, env(&[])),
            Err(ShardError::MissingVariable {
                var: "SLURM_ARRAY_TASK_ID"
            })
        );
    }

    #[test]
    fn slurm_arrays() {
        let s = Shard::from_slurm(env(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "3"),
            ("SLURM_ARRAY_TASK_STEP", "1"),
        ]));
        assert_eq!(s, Ok(Shard { index: 2, count: 4 }));
        // --array=1-8
        let s = Shard::from_slurm(env(&[
            ("SLURM_ARRAY_TASK_ID", "8"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
        ]));
        assert_eq!(s, Ok(Shard { index: 7, count: 8 }));
        assert_eq!(
            Shard::from_slurm(env(&[("SLURM_ARRAY_TASK_COUNT", "8")])),
            Err(ShardError::MissingVariable {
                var: "SLURM_ARRAY_TASK_ID"
            })
        );
        assert_eq!(
            Shard::from_slurm(env(&[("SLURM_ARRAY_TASK_ID", "1")])),
            Err(ShardError::MissingVariable {
                var: "SLURM_ARRAY_TASK_COUNT"
            })
        );
        assert!(matches!(
            Shard::from_slurm(env(&[
                ("SLURM_ARRAY_TASK_ID", "x"),
                ("SLURM_ARRAY_TASK_COUNT", "8")
            ])),
            Err(ShardError::BadVariable { .. })
        ));
        // --array=0-14:2 and --array=1,3,7 cannot be mapped onto 0..N-1
        assert!(matches!(
            Shard::from_slurm(env(&[
                ("SLURM_ARRAY_TASK_ID", "4"),
                ("SLURM_ARRAY_TASK_COUNT", "8"),
                ("SLURM_ARRAY_TASK_STEP", "2")
            ])),
            Err(ShardError::NotConsecutive { .. })
        ));
        assert!(matches!(
            Shard::from_slurm(env(&[
                ("SLURM_ARRAY_TASK_ID", "7"),
                ("SLURM_ARRAY_TASK_COUNT", "3"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_MAX", "7")
            ])),
            Err(ShardError::NotConsecutive { .. })
        ));
    }
}
