"""Reporting: tables (Markdown, LaTeX, CSV), figures and the self-contained HTML report, from
result files only."""
