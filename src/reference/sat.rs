//! Exact triangle–box overlap by clipping the triangle to the box.
