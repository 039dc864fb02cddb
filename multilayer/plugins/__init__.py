"""Rheology plugins: the contract (:mod:`.contract`), the pluggy host (:mod:`.host`) and the
built-in laws (:mod:`.builtins`), registered through the same entry point as third parties."""
