//! Frames from any bytes: the input is a pattern string (up to its first NUL) and an
//! image file (the rest), served by an in-memory loader for the first few frame
//! numbers. The image is decoded on its own, the pattern formatted, and a `frames`
//! form reads them: a decoded image, features or diagnostics, never a panic, and
//! never more memory than the pixel bound allows.
#![no_main]

use std::io;
use std::path::{Path, PathBuf};

use libfuzzer_sys::fuzz_target;
use timbre_lang::frames::{analyse, Image, Numbered, MAX_FRAME_PIXELS};
use timbre_ir::limits::Limits;
use timbre_lang::{CompileOptions, Loader, Registry};

/// The same file for the first `frames` names asked for, then none.
struct Frames {
    bytes: Vec<u8>,
    frames: usize,
    served: std::cell::Cell<usize>,
}

impl Loader for Frames {
    fn load(&self, path: &str, _base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        let served = self.served.get();
        if served >= self.frames {
            return Err(io::Error::new(io::ErrorKind::NotFound, "no more frames"));
        }
        self.served.set(served + 1);
        Ok((PathBuf::from(path), self.bytes.clone()))
    }
}

fuzz_target!(|data: &[u8]| {
    let (pattern, image) = match data.iter().position(|b| *b == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[][..]),
    };
    let pattern = String::from_utf8_lossy(pattern);

    if let Ok(decoded) = Image::decode(image) {
        assert!((decoded.width * decoded.height) as u64 <= MAX_FRAME_PIXELS);
        assert_eq!(decoded.rgb.len(), decoded.width * decoded.height);
        let features = analyse(std::slice::from_ref(&decoded), 1, 0.3);
        assert!(features.iter().flatten().all(|f| f.brightness.is_finite()));
    }
    if let Some(numbered) = Numbered::parse(&pattern) {
        for k in [0, 7, 999, u64::MAX] {
            let _ = numbered.path(k);
        }
    }

    let loader = Frames {
        bytes: image.to_vec(),
        frames: 1 + usize::from(data.first().copied().unwrap_or(0) % 3),
        served: std::cell::Cell::new(0),
    };
    let quoted = format!("{pattern:?}");
    let forms = [
        format!("(frames v :pattern {quoted} :regions 2)"),
        format!("(frames v :files ({quoted} {quoted}) :regions 1 :fps 10)"),
    ];
    let registry = Registry::new();
    for form in forms {
        loader.served.set(0);
        let mut options = CompileOptions::new(&registry, &loader);
        options.limits = Limits {
            memory: 256 << 20,
            ..Limits::default()
        };
        let _ = timbre_lang::compile_str(&form, &options);
    }
});
