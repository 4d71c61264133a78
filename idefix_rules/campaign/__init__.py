"""Campaigns: from a campaign file to a verdict per command chain.

In the order data flows through them: ``input`` (the campaign file, its checks, the sampled
values) → ``simulation`` (command rules,
reference runs, pre-screen, Monte Carlo) → ``storage`` (results.h5) → ``evaluation`` (compiled
rulebook, collisions, statistics from ``statistics``) → ``outcome`` (decision, summary.json,
JUnit). ``runner`` chains the stages; ``worst`` is the worst-case search that replaces the
Monte Carlo stage; the CLI (``idefix_rules.cli.run``) renders them. Which sub-package may
import which (``storage`` and ``statistics`` sit below ``simulation``, which stores and stops
as it runs): ``docs/architecture.md``, "The campaign's stages".
"""
