//! The hostile test suite (issue 20): attacks a tester made on a running deployment, each
//! asserting that nothing is obeyed and nothing is lost.

mod control;
