def register(con):
    pass
