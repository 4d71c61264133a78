"""Campaigns: from a campaign file to a verdict per command chain.

``load`` (schema, positions) → ``sampling`` → ``simulate`` (command rules, reference runs,
pre-screen, Monte Carlo through ``pool`` and ``worker``) → ``store`` (results.h5) →
``evaluation`` (compiled rulebook, collisions) → ``outputs`` (expectations, summary.json,
JUnit). ``runner`` chains the stages; the CLI (``idefix_rules.cli.run``) renders them.
"""
