"""Does a wider batch of sub-environments hurt learning? (see ``__main__``)."""
