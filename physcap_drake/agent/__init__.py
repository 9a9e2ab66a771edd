"""The PhysCaP agent: planner, prioritizer, coder, sandbox and LLM backends."""
