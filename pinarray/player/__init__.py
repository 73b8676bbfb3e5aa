"""The player: trials against absolute deadlines, in this process or one of its own."""
