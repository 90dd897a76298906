"""The dataset: labelling a rendered run (annotation), exports to training formats, statistics,
contact sheets, and the generators of sequence documents. Sits above rendering and converters."""
