"""Design-time document generators: they write scene documents and never render. Balanced
sequence documents (``sequences`` with ``sequence_plans``, ``combinations``, ``laps``,
``balance``) and moving sequences (``motion``)."""
