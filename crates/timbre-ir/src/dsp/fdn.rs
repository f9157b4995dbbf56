//! Late reverberation: a feedback delay network with a given RT60 per band.
