"""What spm_console keeps on disk and reads back: plan files (``plan_file``, validated by
``plan_schema``) and the workspace cache (``workspace_cache``). Run logs live with the
runtime (``motion/logs/runlog.py``)."""
