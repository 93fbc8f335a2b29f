//! Direct photometric alignment (in progress).
