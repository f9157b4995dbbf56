//! Air absorption (ISO 9613-1) and the distance-dependent low-pass that follows it.
