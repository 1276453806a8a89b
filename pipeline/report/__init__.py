"""The `vibro report` document: the pipeline's results as Markdown/HTML with their figures and the answer."""
