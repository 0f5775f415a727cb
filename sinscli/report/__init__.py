"""Rendering: tables, PNG figures, the HTML pages and their script; every number comes from evaluate/ or batch/."""
