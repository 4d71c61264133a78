"""What a campaign hands back: the decision in words (``decision``), and summary.json, JUnit XML
and the exit code (``outputs``)."""
