//! # echofield-backend
//!
//! Sparse Gauss-Newton and Levenberg-Marquardt optimisation of SE(2) pose
//! graphs on faer's sparse Cholesky factorisation.
