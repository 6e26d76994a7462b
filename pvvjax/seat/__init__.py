"""The pilot's seat in three axes: which flight-state inputs each pilot-floor axis's N/rev
needs (`study`: nets of one output per axis, judged per axis by FAA Part 60 test 3.f.1), and
its files and report (`report`, `pvvjax axes`)."""

from .report import axis_summary, axis_table_name, report_section, run_study, write_axis_tables
from .study import AxesStudy, axis_needs, axis_scores, fit_axes, run_axes, study_nets

__all__ = ["AxesStudy", "axis_needs", "axis_scores", "axis_summary", "axis_table_name", "fit_axes", "report_section",
           "run_axes", "run_study", "study_nets", "write_axis_tables"]
