//! Reading what the user gives on standard input: bounded, like every file read
//! (files go through `timbre_lang::read_bounded`, which refuses what is not a regular
//! file before it can block).

use std::io::Read;

/// Standard input, if it holds at most `limit` bytes.
pub fn read_stdin(limit: u64) -> std::io::Result<Vec<u8>> {
    let mut bytes = vec![];
    std::io::stdin()
        .lock()
        .take(limit + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("more than {} MiB, the most a script may be", limit >> 20),
        ));
    }
    Ok(bytes)
}
