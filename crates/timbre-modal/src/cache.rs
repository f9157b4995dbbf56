//! Models cached on disk (written by a later commit).
