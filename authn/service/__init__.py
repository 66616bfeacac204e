"""`authn serve`: the decision engine as an HTTP service (FastAPI + uvicorn).

`create_app(settings)` builds one application: one `Checker` per worker process, loaded at
start-up (lifespan), API keys checked against the database, roles decided by the service's
own Cedar policy (authn/policies/service.cedar). Nothing here is imported by `authn check`.
"""
