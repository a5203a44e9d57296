"""Measurement studies, one file each (`study.py` gives their shape, `registry.py` names them)."""
