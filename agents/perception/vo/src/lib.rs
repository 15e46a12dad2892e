//! RGB-D visual odometry (thesis Algorithm 3), wheel odometry and pose fusion.
#![warn(missing_docs)]
