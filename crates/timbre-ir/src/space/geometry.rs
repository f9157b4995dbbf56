//! Geometry of the space: obstacles, rooms and the paths sound takes between them.
