"""What a campaign hands back: the decision in words (``decision``), values in the units they
were written in (``wording``), and summary.json, JUnit XML and the exit code (``outputs``)."""
