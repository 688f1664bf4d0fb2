"""report: see the README's package map."""

from .campaign import write_campaign_report
from .html import errors_table, write_html_report

__all__ = ["errors_table", "write_campaign_report", "write_html_report"]
