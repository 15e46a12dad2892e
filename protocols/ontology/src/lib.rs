//! Ontologies as FIPA-SL content: FIPA-Agent-Management and the wheelchair ontology.
#![warn(missing_docs)]
