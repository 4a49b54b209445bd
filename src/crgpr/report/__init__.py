"""Reporting: accuracy metrics (``metrics``), the method comparison (``comparison``), the paper's
tables regenerated (``paper``), stage timings (``timing``) and CR-GPR figures (``figures``)."""
