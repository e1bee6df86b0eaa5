"""Assessments of a finished run against published performance standards (docs/pbs.md)."""
