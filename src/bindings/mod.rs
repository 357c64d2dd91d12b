//! PyO3 bindings: the compiled module `kinema._kinema`.
