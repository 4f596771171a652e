"""Experiment design: planned inputs, predicted bounds, steady-versus-unsteady discrimination."""
