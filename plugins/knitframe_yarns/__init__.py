"""Built-in yarns (the yarn library) and yarn constitutive models."""
