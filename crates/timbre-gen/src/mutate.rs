//! Near-valid programs: the text of a valid tree with a few mistakes of the kinds
//! people and programs make (a token dropped, doubled or swapped, a parenthesis too
//! many or too few, a name misspelt or replaced by another node's, a number made
//! extreme, a keyword out of place), for fuzzing the front end and the engines with
//! input close enough to valid to get past the parser.

use rand::{Rng, RngExt};

use timbre_lang::catalogue::NODES;

/// Numbers that break naive code: zero, signs, the edges of f64, huge delays and
/// rates, fractions that never end in binary.
const EXTREMES: &[&str] = &[
    "0", "-0", "-1", "1e308", "-1e308", "1e-308", "5e-324", "1e999", "65536", "1e9", "0.1", "600",
    "-600", "(/ 0 0)", "(/ 1 0)", "(log 0)",
];

/// Tokens of `text`: parentheses, strings and runs of other non-space characters.
fn tokens(text: &str) -> Vec<String> {
    let mut out = vec![];
    let mut chars = text.chars().peekable();
    while let Some(&c) = chars.peek() {
        if c.is_whitespace() {
            chars.next();
        } else if c == '(' || c == ')' {
            out.push(c.to_string());
            chars.next();
        } else if c == '"' {
            let mut s = String::from(c);
            chars.next();
            for d in chars.by_ref() {
                s.push(d);
                if d == '"' {
                    break;
                }
            }
            out.push(s);
        } else {
            let mut s = String::new();
            while let Some(&d) = chars.peek() {
                if d.is_whitespace() || d == '(' || d == ')' {
                    break;
                }
                s.push(d);
                chars.next();
            }
            out.push(s);
        }
    }
    out
}

/// `text` with 1 to `max_mistakes` mistakes drawn from `rng`.
pub fn near_valid(rng: &mut impl Rng, text: &str, max_mistakes: usize) -> String {
    let mut tokens = tokens(text);
    let mistakes = rng.random_range(1..=max_mistakes.max(1));
    for _ in 0..mistakes {
        if tokens.is_empty() {
            tokens.push("(".into());
        }
        let at = rng.random_range(0..tokens.len());
        match rng.random_range(0..9) {
            0 => {
                tokens.remove(at);
            }
            1 => {
                let copy = tokens[at].clone();
                tokens.insert(at, copy);
            }
            2 => {
                let other = rng.random_range(0..tokens.len());
                tokens.swap(at, other);
            }
            3 => tokens.insert(at, if rng.random() { "(" } else { ")" }.into()),
            4 => {
                // Another node's name where a name or number was.
                let spec = &NODES[rng.random_range(0..NODES.len())];
                if tokens[at] != "(" && tokens[at] != ")" {
                    tokens[at] = spec.name.to_string();
                }
            }
            5 => {
                if tokens[at].parse::<f64>().is_ok() || rng.random_range(0..4) == 0 {
                    tokens[at] = EXTREMES[rng.random_range(0..EXTREMES.len())].into();
                }
            }
            6 => {
                // A misspelling: a letter dropped or doubled.
                let word: Vec<char> = tokens[at].chars().collect();
                if word.len() > 1 && word[0].is_alphabetic() {
                    let k = rng.random_range(0..word.len());
                    let mut misspelt: String = word[..k].iter().collect();
                    if rng.random() {
                        misspelt.push(word[k]);
                        misspelt.push(word[k]);
                    }
                    misspelt.extend(&word[k + 1..]);
                    tokens[at] = misspelt;
                }
            }
            7 => {
                let keywords = [":seed", ":max", ":phase", ":lanes", ":interp", ":"];
                tokens.insert(at, keywords[rng.random_range(0..keywords.len())].into());
            }
            _ => {
                // A subtree wrapped in a wide vector, or multiplied by one.
                let wide = ["(iota 64)", "(rvector 32 1 2)", "(vector 1 2 3)"];
                tokens.insert(at, wide[rng.random_range(0..wide.len())].into());
                tokens.insert(at, "*".into());
                tokens.insert(at, "(".into());
                tokens.push(")".into());
            }
        }
    }
    tokens.join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn tokens_keep_strings_and_parentheses() {
        assert_eq!(
            tokens("(sample \"a b.wav\")(+ 1 -2)"),
            ["(", "sample", "\"a b.wav\"", ")", "(", "+", "1", "-2", ")"]
        );
    }

    #[test]
    fn mistakes_change_the_text_and_depend_only_on_the_seed() {
        let text = "(* 0.5 (sine (* t 440)))";
        let mut changed = 0;
        for seed in 0..50 {
            let a = near_valid(&mut rand::rngs::StdRng::seed_from_u64(seed), text, 3);
            let b = near_valid(&mut rand::rngs::StdRng::seed_from_u64(seed), text, 3);
            assert_eq!(a, b);
            changed +=
                usize::from(a.split_whitespace().collect::<String>() != text.replace(' ', ""));
        }
        assert!(changed > 40, "only {changed} of 50 changed");
    }
}
