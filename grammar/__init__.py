"""The rulebook grammar (``rulebook.lark``), shipped as package data of ``idefix_rules.grammar``."""
