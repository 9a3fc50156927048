"""The staggered coupling loop, the participant interfaces, force transfer and its ledger, fake participants."""
