"""GetDP decks and the Python runner that drives the ``getdp`` executable."""
