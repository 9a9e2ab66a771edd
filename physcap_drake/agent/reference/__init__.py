"""The offline reference reasoner: a rule-based stand-in for the language models."""
