"""The experimenter's terminal UI (Textual)."""
