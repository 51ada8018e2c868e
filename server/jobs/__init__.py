"""Durable background jobs: the queue in the database, the worker loop, the pipeline steps."""
