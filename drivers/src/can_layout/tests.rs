//! Layout resolution and decoding.
