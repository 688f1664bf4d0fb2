"""identification: see the README's package map."""
