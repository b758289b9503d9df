"""The protocol runner and the paper's sequences (contact search, ladder, hold)."""
