"""The lint rules, one module per family (each registers its rules when imported)."""
