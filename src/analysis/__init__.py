"""Analysis: the gap and its evidence, the diagnosis's fits and model search, reports, error models.

The gap and its evidence (``gap``, ``evidence``, ``image_evidence``), the diagnosis's candidate
effects, their fits, scores and the model search (``candidates``, ``fitting``, ``appearance``,
``sensor_noise``, ``defocus``, ``channels``, ``scored``, ``scoring``, ``selection``, with its
``thresholds`` and the ``runner`` it is given); reports and figures (``report/``, ``compare``),
the paper's Table 2 (``paper``) and error models for control software (``errormodel/``).
"""
