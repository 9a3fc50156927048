"""The electromagnetic participant: GetDP load provider, users' own decks and their contract check."""
