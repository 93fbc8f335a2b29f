//! ORB features and Hamming matching (in progress).
