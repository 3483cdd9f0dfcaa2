//! Mutation fuzzing on stable Rust: a file's bytes changed at random (replaced, inserted,
//! deleted) and its number tokens replaced by values that break parsers and arithmetic,
//! driven by proptest. `SHERWOOD_FUZZ_CASES` sets the cases per format for a long run.

use proptest::prelude::*;

/// Cases per format: `SHERWOOD_FUZZ_CASES`, or a few dozen.
pub fn cases() -> u32 {
    std::env::var("SHERWOOD_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(48)
}

/// Values that break parsers and arithmetic, put in place of a number.
pub const EXTREMES: [&str; 12] = [
    "NaN",
    "inf",
    "-inf",
    "1e38",
    "-1e38",
    "-1",
    "0",
    "4294967295",
    "18446744073709551615",
    "1e-45",
    "99999999999999999999999",
    "0.5",
];

/// One change to a text: a byte replaced, inserted or deleted, or a number token replaced
/// by an extreme value.
#[derive(Clone, Debug)]
pub enum Mutation {
    Byte { at: usize, byte: u8 },
    Insert { at: usize, byte: u8 },
    Delete { at: usize },
    Number { which: usize, value: usize },
}

pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Byte { at, byte }),
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Insert { at, byte }),
        any::<usize>().prop_map(|at| Mutation::Delete { at }),
        (any::<usize>(), 0..EXTREMES.len())
            .prop_map(|(which, value)| Mutation::Number { which, value }),
        (any::<usize>(), 0..EXTREMES.len())
            .prop_map(|(which, value)| Mutation::Number { which, value }),
    ]
}

pub fn mutate(bytes: &[u8], mutations: &[Mutation]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    for m in mutations {
        let len = out.len().max(1);
        match *m {
            Mutation::Byte { at, byte } => {
                if !out.is_empty() {
                    out[at % len] = byte;
                }
            }
            Mutation::Insert { at, byte } => out.insert(at % (out.len() + 1), byte),
            Mutation::Delete { at } => {
                if !out.is_empty() {
                    out.remove(at % len);
                }
            }
            Mutation::Number { which, value } => {
                // Number tokens: runs of digits (with a sign, point or exponent).
                let mut tokens = Vec::new();
                let mut i = 0;
                while i < out.len() {
                    if out[i].is_ascii_digit() {
                        let start = i;
                        while i < out.len()
                            && (out[i].is_ascii_digit() || b".eE-+".contains(&out[i]))
                        {
                            i += 1;
                        }
                        tokens.push(start..i);
                    } else {
                        i += 1;
                    }
                }
                if !tokens.is_empty() {
                    let range = tokens[which % tokens.len()].clone();
                    out.splice(range, EXTREMES[value].bytes());
                }
            }
        }
    }
    out
}
