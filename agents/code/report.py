print("THOUGHT: $thought | ACTION: none")
