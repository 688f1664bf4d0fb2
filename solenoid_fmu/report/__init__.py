"""report: see the README's package map."""

from .html import errors_table, write_html_report

__all__ = ["errors_table", "write_html_report"]
