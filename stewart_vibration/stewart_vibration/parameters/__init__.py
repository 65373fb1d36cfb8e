"""The nodes' parameters declared once: specs (spec.py), one table per node (tables.py), the generated docs
(docs.py)."""
