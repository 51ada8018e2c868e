"""Domain services: keyword-only functions over a Session; they flush, never commit."""
