//! UDP and TCP frame transports, and a seeded UDP impairment proxy.
#![warn(missing_docs)]
