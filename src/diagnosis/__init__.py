"""Diagnosis: where the gap lies, which effect explains it, how far it shrinks; blind validation."""
