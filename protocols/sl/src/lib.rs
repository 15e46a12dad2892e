//! FIPA-SL content language (SC00008): SL0, SL1, SL2 and full SL.
#![warn(missing_docs)]
