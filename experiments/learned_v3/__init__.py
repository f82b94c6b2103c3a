"""Learned agents on the v3 RowScale ids (see ``__main__``)."""
